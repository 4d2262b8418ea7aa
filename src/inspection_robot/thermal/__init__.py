"""Thermal imager: driver interface, vendor plug-ins, radiometric files and command handling."""
