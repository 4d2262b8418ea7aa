"""Simulated devices and world, behind the same driver interfaces as the real ones."""
