"""Command-line calibration tool: ``calibrate_preset PRESET_DIR TARGETS_YAML [--optics FILE]``.

Not a ROS node (no rospy): it lives here so ``rosrun inspection_robot calibrate_preset`` finds
it. TARGETS_YAML holds ``targets: [{kind: pointer, box: [8 numbers], start_angle: ..}, ..]``
(see inspection.calibration); the optics file is config/camera_optics.yaml. Writes
preset_calib_info.ini and zoomX.xml into PRESET_DIR; exits 1 with the reason on bad input.
"""
import argparse
import os
import sys

import yaml

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.inspection.calibration import calibrate
from inspection_robot.inspection.preset import PresetError


def default_optics_file():
    here = os.path.dirname(os.path.abspath(__file__))
    for candidate in (os.path.join(here, "..", "..", "..", "config", "camera_optics.yaml"),):
        if os.path.isfile(candidate):
            return os.path.normpath(candidate)
    return None


def run(argv=None):
    """The tool; returns the exit status."""
    parser = argparse.ArgumentParser(description="Calibrate the target boxes of a recorded preset.")
    parser.add_argument("preset_dir")
    parser.add_argument("targets_yaml")
    parser.add_argument("--optics", default=default_optics_file(), help="camera_optics.yaml")
    args = parser.parse_args(argv)
    try:
        with open(args.targets_yaml) as f:
            specs = (yaml.safe_load(f) or {}).get("targets", [])
        if not args.optics:
            raise PresetError("no optics file found; pass --optics")
        with open(args.optics) as f:
            optics_cfg = yaml.safe_load(f)["camera_optics"]
        optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
        targets = calibrate(args.preset_dir, specs, optics)
    except (OSError, yaml.YAMLError, KeyError, ValueError, PresetError) as err:
        sys.stderr.write("calibrate_preset: %s\n" % (err,))
        return 1
    sys.stdout.write("calibrated %d target(s) in %s\n" % (len(targets), args.preset_dir))
    return 0


def main(argv=None):
    sys.exit(run(argv))
