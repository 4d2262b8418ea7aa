"""Unattended patrol: task parsing (spec), the task state machine (patrol), the results store
(store, SQLite) and patrol reports (report). Pure Python, no ROS; nodes/task_manager.py wires it."""
