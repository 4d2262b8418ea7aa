"""Thermal imager driver interface (vendor plug-ins are loaded with inspection_robot.plugin).

A driver delivers radiometric frames (float32 degC per pixel) and may support only a subset of
the spec's commands (vendors differ): ``supports(command)`` says which; the command table answers
the rest ``failed``/``unsupported``, and so does a request the device itself reports it cannot do
(``ThermalUnsupported``: a fixed lens asked to focus, a camera without a temperature matrix).
Built-in: ``isapi`` (thermal.isapi, Hikvision). Vendor plug-ins are classes named
"package.module:Class" (parameter ``~driver``), constructed with keyword arguments from ``~driver_params``.
"""
from inspection_robot.drivers import not_fitted_reason


class ThermalError(Exception):
    """The imager could not carry out a request; the message is the reason."""


class ThermalUnreachable(ThermalError):
    """No exchange with the imager (connection refused or reset, timeout)."""


class ThermalRefused(ThermalError):
    """The imager refused the credentials."""


class ThermalUnsupported(ThermalError):
    """The imager reports that it cannot do this (the command answers ``failed``/``unsupported``)."""


class ThermalDriver(object):
    """Interface of a radiometric thermal imager."""

    #: commands of INTERFACE.md this driver can serve (subset of interface.INFRARED_COMMANDS)
    supported = ()

    def supports(self, command):
        return command in self.supported

    def frame(self):
        """The current radiometric frame: 2-D float32 array, degC."""
        raise NotImplementedError

    def capture_jpeg(self):
        """The imager's own picture as JPEG bytes (its palette), pixel for pixel the frame's when the
        imager delivers frames, or None: capture_picture then writes a false-colour picture of ``frame()``."""
        return None

    def auto_focus(self):
        raise NotImplementedError

    def probe(self):
        """Raises ThermalError when the imager does not answer."""
        raise NotImplementedError

    def close(self):
        pass


class NoImager(ThermalDriver):
    """``~driver: none`` (no imager fitted): every request fails with the reason, diagnostics show ERROR."""

    supported = ("save_temperature", "capture_picture", "get_max_temperature", "get_spot_temperature",
                 "get_high_temperature", "get_low_temperature", "auto_focus", "set_measure_spot")
    REASON = not_fitted_reason("thermal")

    def frame(self):
        raise ThermalError(self.REASON)

    def auto_focus(self):
        raise ThermalError(self.REASON)

    def probe(self):
        raise ThermalError(self.REASON)
