"""Preset recording without ROS: pictures at the final and wider zooms, preset.ini, atomically.

The preset_scale node gathers the state (pan/tilt, zoom, focus, pose) and passes a head (see
inspection.finder.Head) that takes pictures; this module decides the zoom ladder, writes
everything into a temporary directory and renames it to ``<root>/<preset_id>/<stamp>/``.
"""
import os

from inspection_robot.files import FileError, write_atomic
from inspection_robot.inspection.preset import PresetDirWriter, PresetInfo, zoom_picture_name

MAX_WIDE_PICTURES = 6
THERMAL_PICTURE = "thermal.jpg"
THERMAL_FRAME = "thermal.png"   # 16-bit PNG, centikelvin (infrared_imager's save_temperature format)


def zoom_ladder(final_zoom, min_zoom, factor=2.0, count=MAX_WIDE_PICTURES):
    """[final, final/2, final/4, ...] down to the widest zoom, at most 1 + ``count`` levels."""
    levels = [float(final_zoom)]
    while len(levels) <= count and levels[-1] > min_zoom * 1.0001:
        levels.append(max(levels[-1] / factor, float(min_zoom)))
    return levels


def record_preset(head, root, preset_id, stamp, state, infrared=False, preset_type="", extra_data="",
                  min_zoom=1.0, arm_trajectory=None):
    """Record a preset; returns its final directory. Raises on failure, leaving nothing behind.

    ``state``: dict pan_deg, tilt_deg, zoom, focus_position, pose (x, y, yaw) and width/height
    of the pictures. The zoom is restored to ``state['zoom']`` at the end, also on failure.
    ``arm_trajectory``: a file to copy into the preset (extra_data field 0 = 1).
    """
    levels = zoom_ladder(state["zoom"], min_zoom)
    with PresetDirWriter(root, preset_id, stamp) as writer:
        width = height = 0
        try:
            for k, level in enumerate(levels):
                if k > 0:
                    head.set_zoom(level)
                image = head.capture(writer.file(zoom_picture_name(k)))
                height, width = image.shape[:2]
        finally:
            if len(levels) > 1:
                head.set_zoom(levels[0])
        thermal_picture = thermal_frame = ""
        if infrared:
            head.capture_thermal(writer.file(THERMAL_PICTURE), writer.file(THERMAL_FRAME))
            thermal_picture, thermal_frame = THERMAL_PICTURE, THERMAL_FRAME
        arm_name = ""
        if arm_trajectory:
            arm_name = os.path.basename(arm_trajectory)
            try:
                with open(arm_trajectory, "rb") as f:
                    trajectory = f.read()
            except OSError as err:
                raise FileError("cannot read the arm trajectory '%s': %s" % (arm_trajectory, err.strerror or err))
            write_atomic(writer.file(arm_name), trajectory)   # fsynced like the pictures before the commit
        info = PresetInfo(preset_id, preset_type, infrared, stamp, state["pan_deg"], state["tilt_deg"],
                          state["zoom"], state.get("focus_position", 0), state["pose"], levels, width, height,
                          extra_data=extra_data, thermal_picture=thermal_picture, thermal_frame=thermal_frame,
                          arm_trajectory=arm_name)
        write_atomic(writer.file("preset.ini"), info.to_ini())
        return writer.commit()
