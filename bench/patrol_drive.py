"""The simulated yard's patrol drives in simulated time: where a drive's time goes, without ROS.

``drive_patrol()`` orders config/sim_world.yaml's patrol stops (inspection_robot_testing.yard_patrol)
like task_manager's ``order: "shortest"`` (planner path lengths, home closes the tour), then drives
each leg to a stop (a patrol ends at its last stop) as move_base, robot_control and the chassis
simulator would: Approach(PathFollower) at move_base's control_rate -> MotionController at
robot_control's rate -> SimChassis, all with the parameters of config/move_base.yaml and
config/robot_control.yaml, on a fake clock (the machine's
load cannot distort it). Poses reach the follower as the simulated localizer would send them:
``truth`` (sim/true_pose, every control cycle) or ``noisy`` (sim_localizer.yaml: noise, rate,
latency). Between legs the robot stands still for ``preset_s`` per preset (the inspection: 0.3 to
1.3 s per preset in `make patrol`), as in a patrol.

Every 10 ms of a drive goes to one phase: ``switch`` (the chassis turns its wheels between
straight and steer mode), ``align`` (spin in place towards the path), ``spin`` (to the goal's
yaw), ``settle`` (waiting for a pose at rest), ``correct`` (driving back into tolerance), or
``track`` (pure pursuit). Each 10 ms also splits into the share the bound counts (speed / the
goal's speed: progress at full speed) and the time lost, charged to why the speed was lower:
``accel`` (the chassis still accelerating to the command), ``goal_decel`` (braking profile to the
goal), ``corner`` (corner speed, curvature cap), ``proximity`` (near obstacles); all of a
non-track phase is lost. The bound is the planned length at the goal speed, so the lost times add
up to the drives' time minus the bound (up to path shortcuts in corners).
"""
import os
import sys

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "src"))

from inspection_robot.interface import MOVE_VELOCITY_X_UNIT_M_S, MOVE_VELOCITY_YAW_UNIT_RAD_S, SENDER_MOVE_BASE  # noqa
from inspection_robot.interface import WHEEL_STRAIGHT  # noqa: E402
from inspection_robot.motion.controller import MotionController  # noqa: E402
from inspection_robot.motion.velocity import VelocityLimits  # noqa: E402
from inspection_robot.nav.costmap import Costmap  # noqa: E402
from inspection_robot.nav.curves import shape_path  # noqa: E402
from inspection_robot.nav.follower import ALIGN, DONE, SETTLE, SPIN, Approach, FollowerParams, PathFollower  # noqa
from inspection_robot.nav.goal import MoveGoal  # noqa: E402
from inspection_robot.nav.gridmap import load_map  # noqa: E402
from inspection_robot.nav.planner import Planner  # noqa: E402
from inspection_robot.nav.tour import order_points  # noqa: E402
from inspection_robot.sim.chassis import SimChassis  # noqa: E402
from inspection_robot.sim.noisy_localizer import NoisyLocalizer  # noqa: E402
from inspection_robot_testing.yard_patrol import YARD_STOPS  # noqa: E402

TICK = 0.01    # s, physics and bookkeeping step
PHASES = ("track", "align", "spin", "switch", "settle", "correct")
LOSSES = ("accel", "goal_decel", "corner", "proximity", "align", "spin", "switch", "settle", "correct")


def _config(name):
    with open(os.path.join(ROOT, "config", name)) as f:
        return yaml.safe_load(f)


def yard_route(planner, start_xy, home_xy):
    """The stops in task_manager's shortest order and the planned length (start -> stops -> home)."""
    points = [tuple(start_xy)] + [pose[:2] for _n, pose, _p in YARD_STOPS] + [tuple(home_xy)]
    order, length, _ = order_points(points, lambda i, j: planner.plan(points[i], points[j]).length)
    return [YARD_STOPS[i - 1] for i in order[1:-1]], length


class Leg(object):
    """One drive's bookkeeping: seconds per phase and seconds lost per cause."""

    def __init__(self, name, planned_m, speed):
        self.name, self.planned_m, self.speed = name, planned_m, speed
        self.phase_s = dict.fromkeys(PHASES, 0.0)
        self.lost_s = dict.fromkeys(LOSSES, 0.0)
        self.seconds = 0.0

    def add(self, phase, lost_cause=None, lost=1.0):
        self.seconds += TICK
        self.phase_s[phase] += TICK
        if lost_cause is not None:
            self.lost_s[lost_cause] += TICK * lost


def yard_planner():
    """move_base's planner on the simulated yard's map, with config/move_base.yaml's inflation."""
    move_base = _config("move_base.yaml")
    grid = load_map(os.path.join(ROOT, "config", "maps", "substation.yaml"))
    costmap = Costmap(grid, move_base["robot_radius"], move_base["safety_margin"], move_base["margin_cost"])
    return Planner(costmap, move_base["coarse_factor"])


def home_pose():
    return tuple(float(v) for v in _config("sim_site.yaml")["task_manager"]["home_pose"])


def drive_patrol(follower_overrides=None, localizer="truth", preset_s=0.5, seed=1, task_overrides=None):
    """Drive the yard's patrol; returns (legs, planned length of the legs driven m, drive speed m/s)."""
    move_base, control, task = _config("move_base.yaml"), _config("robot_control.yaml"), _config("task_manager.yaml")
    site = _config("sim_site.yaml")
    planner = yard_planner()
    costmap = planner.costmap
    values = dict(move_base["follower"])
    values.update(follower_overrides or {})
    params = FollowerParams(**values)
    task.update(task_overrides or {})
    turn_at_stops = bool(task["turn_at_stops"])   # the yard's stops are not precision stops
    speed, yaw_speed = float(task["velocity_x"]), float(task["velocity_yaw"])
    start = tuple(float(v) for v in site["move_base"]["init_pose"])
    home = home_pose()
    stops, _tour_m = yard_route(planner, start[:2], home[:2])
    clock = [0.0]
    sim = dict(control["sim"])
    chassis = SimChassis(lambda: clock[0], start, **{k: v for k, v in sim.items()
                                                     if k not in ("battery_soc", "battery_time_scale")})
    controller = MotionController(chassis, VelocityLimits(control["max_velocity_x"], control["max_velocity_yaw"],
                                                          control["refuse_velocity_x"],
                                                          control["refuse_velocity_yaw"]),
                                  control["cmd_timeout"], lambda: clock[0])
    period = int(round(1.0 / move_base["control_rate"] / TICK))
    control_period = int(round(1.0 / control["rate"] / TICK))
    noisy = None
    if localizer == "noisy":
        loc = _config("sim_localizer.yaml")
        noisy = NoisyLocalizer(loc["sigma_xy"], loc["sigma_yaw"], loc["latency"], seed=seed)
        pose_period = int(round(1.0 / loc["rate"] / TICK))
    legs, step = [], 0
    # a patrol ends at its last stop: home only closes the tour the order is chosen by
    for name, goal_pose, presets in stops:
        (x, y, _yaw), _v = chassis.true_pose()
        plan = planner.plan((x, y), goal_pose[:2])
        goal = MoveGoal(goal_pose[0], goal_pose[1], goal_pose[2], turn_at_stops, False, False, speed, yaw_speed)
        follower = PathFollower(shape_path(plan.points, chassis.true_pose()[0], goal, params, costmap.clearance),
                                goal, params, costmap.clearance)
        approach = Approach(follower)
        leg = Leg(name, plan.length, speed)
        stamp, pose, phase, cmd = None, None, None, None
        while True:
            true_pose, (vx, _wz) = chassis.true_pose()
            if noisy is None:
                if step % period == 0:
                    stamp, pose = clock[0], true_pose
            else:
                noisy.add(clock[0], clock[0], true_pose)
                if step % pose_period == 0:
                    out = noisy.output(clock[0])
                    if out is not None:
                        stamp, pose = out
            if step % period == 0 and pose is not None:
                progress = approach.step(clock[0], stamp, pose)
                phase = progress.phase
                if phase == DONE:
                    break
                cmd = progress.command
                controller.on_move_cmd(SENDER_MOVE_BASE, cmd.velocity_x / MOVE_VELOCITY_X_UNIT_M_S,
                                       cmd.velocity_yaw / MOVE_VELOCITY_YAW_UNIT_RAD_S, cmd.wheel_control)
            if step % control_period == 0:
                controller.tick()
            _account(leg, phase, approach, chassis, cmd, vx, speed)
            clock[0] += TICK
            step += 1
            if leg.seconds > 600.0:
                raise RuntimeError("leg to %s not finished in 600 s" % name)
        legs.append(leg)
        controller.on_move_cmd(SENDER_MOVE_BASE, 0, 0, WHEEL_STRAIGHT)   # move_base's stop at the goal's end
        for _ in range(int(round(preset_s * len(presets) / TICK))):   # the inspection: the robot stands
            if step % control_period == 0:
                controller.tick()
            clock[0] += TICK
            step += 1
    return legs, sum(leg.planned_m for leg in legs), speed


def _account(leg, phase, approach, chassis, cmd, vx, speed):
    state = chassis.state()
    if state.switching or (cmd is not None and cmd.wheel_control != state.wheel_mode):
        leg.add("switch", "switch")
    elif phase == SETTLE:
        leg.add("settle", "settle")
    elif approach.corrections:
        leg.add("correct", "correct")
    elif phase == ALIGN:
        leg.add("align", "align")
    elif phase == SPIN:
        leg.add("spin", "spin")
    else:
        share = min(abs(vx) / speed, 1.0)
        lost = 1.0 - share
        if lost < 1e-3:
            leg.add("track")
        elif cmd is not None and abs(vx) < abs(cmd.velocity_x) - 1e-3:
            leg.add("track", "accel", lost)
        else:
            limit = getattr(approach.follower, "limit", "corner")
            leg.add("track", limit if limit in LOSSES else "corner", lost)


def summary(legs, planned, speed):
    """Totals: drive seconds, the bound, seconds per phase and lost seconds per cause."""
    total = sum(leg.seconds for leg in legs)
    phases = {k: round(sum(leg.phase_s[k] for leg in legs), 1) for k in PHASES}
    lost = {k: round(sum(leg.lost_s[k] for leg in legs), 1) for k in LOSSES}
    return {"drive_s": round(total, 1), "bound_s": round(planned / speed, 1), "planned_m": round(planned, 2),
            "ratio": round(total / (planned / speed), 3), "legs": len(legs), "phase_s": phases, "lost_s": lost}


if __name__ == "__main__":
    import json
    for mode in ("truth", "noisy"):
        legs, planned, speed = drive_patrol(localizer=mode)
        print(json.dumps(dict(summary(legs, planned, speed), localizer=mode)))
        for leg in legs:
            print("   %-22s %5.1f m  %5.1f s (bound %5.1f) %s" % (
                leg.name, leg.planned_m, leg.seconds, leg.planned_m / speed,
                {k: round(v, 1) for k, v in leg.lost_s.items() if v >= 0.05}))
