"""Heartbeat and robot_status merging (status_control)."""
