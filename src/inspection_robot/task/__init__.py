"""Unattended patrol: task parsing (spec), the task state machine (patrol), the results store
(store, SQLite), patrol reports (report) and task_manager's whole task life behind one class
(service.TaskService). Pure Python, no ROS; nodes/task_manager.py wires it."""
