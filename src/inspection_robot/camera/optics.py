"""Zoom -> field of view of the visible camera, shared by the camera, preset_rotate and find_scale.

The table (config/camera_optics.yaml) gives the horizontal field of view at a few zoom levels
(magnification); between them the focal length, not the angle, is interpolated, since a zoom
lens moves its focal length. Vertical FOV follows from the picture's aspect ratio (square pixels).
"""
import bisect
import math


def focal_for_hfov(width, hfov_deg):
    """Focal length in px of a lens with horizontal field of view ``hfov_deg`` on a picture ``width`` px wide."""
    return width / 2.0 / math.tan(math.radians(hfov_deg) / 2.0)


class ZoomOptics(object):
    def __init__(self, zoom_hfov_deg, width, height):
        """``zoom_hfov_deg``: [[zoom, hfov_deg], ...] with increasing zoom; width/height in px."""
        table = sorted((float(z), float(f)) for z, f in zoom_hfov_deg)
        if len(table) < 2 or any(f <= 0 or f >= 180 for _, f in table) or table[0][0] <= 0:
            raise ValueError("zoom_hfov_deg needs >= 2 rows of positive zoom and 0 < hfov < 180")
        self.width = int(width)
        self.height = int(height)
        self.zooms = [z for z, _ in table]
        # focal length in pixels at each table row
        self._focal_px = [focal_for_hfov(self.width, f) for _, f in table]

    @property
    def min_zoom(self):
        return self.zooms[0]

    @property
    def max_zoom(self):
        return self.zooms[-1]

    def focal_px(self, zoom, width=None):
        """Focal length in pixels at ``zoom`` for a picture ``width`` px wide (default: native)."""
        zoom = min(max(float(zoom), self.zooms[0]), self.zooms[-1])
        i = min(max(bisect.bisect_right(self.zooms, zoom) - 1, 0), len(self.zooms) - 2)
        z0, z1 = self.zooms[i], self.zooms[i + 1]
        t = (zoom - z0) / (z1 - z0)
        focal = self._focal_px[i] + t * (self._focal_px[i + 1] - self._focal_px[i])
        return focal * (width if width is not None else self.width) / float(self.width)

    def hfov_deg(self, zoom):
        return math.degrees(2.0 * math.atan(self.width / 2.0 / self.focal_px(zoom)))

    def vfov_deg(self, zoom):
        return math.degrees(2.0 * math.atan(self.height / 2.0 / self.focal_px(zoom)))

    def pixel_to_angles(self, zoom, delta_x, delta_y, width, height):
        """Pan/tilt change (deg, standard convention: pan CCW +, tilt down +) that brings the
        pixel at (centre + delta) to the centre of a ``width`` x ``height`` picture of this view.
        delta_x is right +, delta_y up + (the PresetRotate convention)."""
        focal = self.focal_px(zoom, width)
        pan = -math.degrees(math.atan2(delta_x, focal))
        tilt = -math.degrees(math.atan2(delta_y, math.hypot(focal, delta_x)))
        return pan, tilt
