"""Inspection pipeline: presets, calibration, target localisation and meter reading (no rospy)."""
