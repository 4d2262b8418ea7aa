"""Charging: the dock's geometry and charge_control's docking state machine (no rospy)."""
