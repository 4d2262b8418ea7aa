"""Command-line calibration tool (not a ROS node: no rospy; it lives with the nodes so it is
installed beside them: ``scripts/rosenv calibrate_preset ...``, or ``rosrun inspection_robot
calibrate_preset ...`` in an ordinary catkin workspace).

    calibrate_preset PRESET_DIR TARGETS_YAML [--optics FILE]
    calibrate_preset PRESET_DIR --from-world [WORLD_YAML] [--only ID[,ID...]] [--optics FILE]
                     [--thermal-hfov DEG] [--thermal-size WxH] [--pose X,Y,YAW]
    calibrate_preset PRESET_DIR --command CMD JSON [--optics FILE]

TARGETS_YAML holds ``targets: [{kind: pointer, box: [8 numbers], start_angle: ..}, ..]`` (see
inspection.calibration). ``--from-world`` calibrates from the simulated world's ground truth
instead (default world: config/sim_world.yaml): every face the recorded view sees well (and, for
infrared presets, every hot spot in both pictures) becomes a target (sim.inspection_sim
.calibrate_from_world). ``--pose``: where the simulated robot really stood when the preset was
recorded (map m, m, rad); preset.ini holds the localizer's pose, which is noisy in simulation too
(sim_localizer), so a test that put the robot somewhere passes that pose. The optics file is
config/camera_optics.yaml. Writes preset_calib_info.ini and zoomX.xml into PRESET_DIR and prints one
line per target; exits 1 with the reason on bad input, writing nothing.

``--command`` runs one of the calibration_control commands (mark_box, set_meter_type, set_zero,
set_full_scale, set_values, remove_target, clear_draft, get, apply, upload; docs/interface.md) on
PRESET_DIR through the same code the robot serves over the link (inspection.calibration_commands);
JSON is the command's data without "preset". Prints the answer.
"""
import argparse
import json
import math
import os
import sys

import yaml

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.command import CommandError
from inspection_robot.inspection.calibration import SelfCheck, calibrate
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.inspection.preset import PresetError
from inspection_robot.interface import ACK_SUCCESS
from inspection_robot.ros.package_share import share_file


def _config_file(name):
    here = os.path.dirname(os.path.abspath(__file__))
    candidate = os.path.normpath(os.path.join(here, "..", "..", "..", "config", name))
    if os.path.isfile(candidate):
        return candidate
    candidate = share_file("config", name)   # installed / devel space; None: the user passes the file
    return candidate if candidate and os.path.isfile(candidate) else None


def default_optics_file():
    return _config_file("camera_optics.yaml")


def _size(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError("expected WxH, e.g. 384x288")
    return width, height


def _pose(text):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError("expected X,Y,YAW (m, m, rad), e.g. 30.0,14.5,-1.5708")
    return tuple(values)


def run(argv=None):
    """The tool; returns the exit status."""
    parser = argparse.ArgumentParser(description="Calibrate the target boxes of a recorded preset.")
    parser.add_argument("preset_dir")
    parser.add_argument("targets_yaml", nargs="?", help="target descriptions (not with --from-world)")
    parser.add_argument("--from-world", nargs="?", const="", default=None, metavar="WORLD_YAML",
                        help="calibrate from the simulated world's ground truth (default config/sim_world.yaml)")
    parser.add_argument("--only", default="", help="with --from-world: comma separated face/hot spot ids to keep")
    parser.add_argument("--optics", default=default_optics_file(), help="camera_optics.yaml")
    parser.add_argument("--thermal-hfov", type=float, default=25.0, help="thermal lens hfov, deg (--from-world)")
    parser.add_argument("--thermal-size", type=_size, default=(384, 288), help="thermal picture WxH (--from-world)")
    parser.add_argument("--pose", type=_pose, default=None,
                        help="with --from-world: X,Y,YAW the robot really stood at (default: preset.ini's, "
                             "the localizer's)")
    parser.add_argument("--command", nargs=2, metavar=("CMD", "JSON"),
                        help="one calibration_control command on PRESET_DIR (JSON without \"preset\")")
    args = parser.parse_args(argv)
    if sum(x is not None for x in (args.from_world, args.targets_yaml, args.command)) != 1:
        parser.error("give one of TARGETS_YAML, --from-world or --command")
    check = SelfCheck()
    try:
        if not args.optics:
            raise PresetError("no optics file found; pass --optics")
        with open(args.optics) as f:
            optics_cfg = yaml.safe_load(f)["camera_optics"]
        optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
        if args.command is not None:
            return _run_command(args.preset_dir, optics, *args.command)
        if args.from_world is not None:
            # the simulator only when asked to calibrate from it: a robot's calibration never loads it
            from inspection_robot.sim.inspection_sim import calibrate_from_world
            from inspection_robot.sim.world import World
            world_file = args.from_world or _config_file("sim_world.yaml")
            if not world_file:
                raise PresetError("no world file found; pass --from-world WORLD_YAML")
            names = [n for n in args.only.split(",") if n] or None
            targets = calibrate_from_world(args.preset_dir, World.load(world_file), optics,
                                           thermal_hfov_deg=args.thermal_hfov, thermal_size=args.thermal_size,
                                           names=names, check=check, true_pose=args.pose)
        else:
            with open(args.targets_yaml) as f:
                specs = (yaml.safe_load(f) or {}).get("targets", [])
            targets = calibrate(args.preset_dir, specs, optics, check=check)
    # (a bad world file raises sim.world.WorldError, a ValueError)
    except (OSError, yaml.YAMLError, KeyError, ValueError, PresetError, CommandError) as err:
        sys.stderr.write("calibrate_preset: %s\n" % (err,))
        return 1
    for i, target in enumerate(targets):
        sys.stdout.write("target_%d %s %s\n" % (i, target.kind, target.name))
    for result in check.results:   # what the reader makes of each meter on the calibration picture
        sys.stdout.write("self-check target_%d %s: read %s (confidence %s)%s%s\n" % (
            result["target"], result["name"], result["read"], result["confidence"],
            "" if result["expected"] is None else ", expected %s, %s %% of full scale apart"
            % (result["expected"], result["apart_fs_pct"]), ": " + result["reason"] if result["reason"] else ""))
    sys.stdout.write("calibrated %d target(s) in %s\n" % (len(targets), args.preset_dir))
    return 0


def _run_command(preset_dir, optics, cmd, data):
    """One calibration_control command on ``preset_dir``; pictures may come from anywhere the
    operator can read (the robot's service confines them to its data roots)."""
    preset_dir = os.path.abspath(preset_dir)
    try:
        fields = json.loads(data)
    except ValueError as err:
        raise PresetError("JSON is not valid: %s" % err)
    if not isinstance(fields, dict):
        raise PresetError("JSON must be an object")
    fields["preset"] = preset_dir
    reply = CalibrationCommands(preset_dir, [preset_dir], [os.sep], optics).table.dispatch(cmd, json.dumps(fields))
    if reply.ack != ACK_SUCCESS:
        raise CommandError(reply.data)
    sys.stdout.write(reply.data + "\n")
    return 0


def main(argv=None):
    sys.exit(run(argv))
