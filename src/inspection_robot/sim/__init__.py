"""Simulated devices and world behind the same interfaces as the real ones."""
