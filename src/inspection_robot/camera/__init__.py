"""Visible camera: optics model, drivers (Hikvision ISAPI, simulated) and command handling."""
