"""charge_control: docks and charges the robot when its battery runs low (docs/interface.md, "Charging").

The docking sequence, thresholds and retries are charge.machine.ChargeMachine; this node only
wires it. Every input (robot_status, task_status, move_action results, task_control replies,
a timer tick) becomes an event handled in order on one worker thread; commands take the same lock.

Subscribes:  robot_status (RobotStatus, only from status_control's caller id: motion.owners, ~owners):
             battery_quantity, battery_status b4 (charging),
                 light_status b0 (relay), mode, position/orientation
             task_status (GeneralTopic, JSON {"state": ...}): task_manager's latched status
Publishes:   charge_status (GeneralTopic, latched): JSON status, on every change
             charge_ack (GeneralAck): replies to charge_cmd, and an unprompted `failed` ack per alarm
             control_cmd (GeneralCmd): enable_charge / disable_charge (sender charge_control)
             voice_cmd (VoiceCmd): prompts and alarms (clips with built-in phrases)
Services:    charge_control (ControlService): twin of charge_cmd/charge_ack: dock, undock, status
Clients:     move_action (GeneralAction) to the dock; task_control (ControlService) pause/resume "charge"
Parameters:  config/charge_control.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); ~dock ({pose, approach_pose, tolerance_m, tolerance_yaw}), a site setting
             without default (the site file; sim.launch: config/sim_site.yaml); ~owners (test rigs only:
             motion/ros_owner_gate.py)
"""
import itertools
import json
import threading

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus

from inspection_robot.charge.dock import parse_dock
from inspection_robot.charge.machine import ChargeMachine
from inspection_robot.charge.ports import ChargeConfig, ChargePorts, battery_from_robot_status
from inspection_robot.command import failed
from inspection_robot.interface import ACK_SUCCESS, MOVE_GOAL_TYPE, MOVE_RESULT_SUCCESS, VOICE_LANGUAGES
from inspection_robot.motion.owners import ROBOT_STATUS
from inspection_robot.msg import GeneralAction, GeneralCmd, GeneralGoal, GeneralTopic, RobotStatus, VoiceCmd
from inspection_robot.nav.goal import move_goal_data
from inspection_robot.ros.actions import server_unavailable
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.language import voice_language
from inspection_robot.ros.node import NodeSettings, init_node, site_param
from inspection_robot.motion.ros_owner_gate import OwnerGate
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.srv import ControlService

NODE_NAME = "charge_control"
EVENT_QUEUE = 1000
SERVER_WAIT_S = 0.05  # s the event thread waits for move_action's server before the machine asks again


class _LockedTable(object):
    """The machine's command table, dispatched under the node's lock (commands arrive on other threads)."""

    def __init__(self, table, lock):
        self._table = table
        self._lock = lock

    def dispatch(self, cmd, data):
        with self._lock:
            return self._table.dispatch(cmd, data)


class RosPorts(ChargePorts):
    """ChargePorts over ROS. Replies come back as events; nothing here calls the machine."""

    def __init__(self, events, task_service, task_timeout, speeds, language):
        self._events = events
        self._speeds = speeds  # (approach velocity_x, dock velocity_x, velocity_yaw)
        self._language = language
        self._task_timeout = task_timeout
        self._trans_ids = itertools.count(1)
        self._task_proxy = rospy.ServiceProxy(task_service, ControlService)
        self._task_service = task_service
        self._task_worker = RequestWorker(NODE_NAME + ": task_control", self._call_task, self._refuse_task, 10)
        # the plain ActionClient: SimpleActionClient logs an error for the finished goal's late status
        # whenever a new goal follows at once (approach -> dock -> relay -> back off does exactly that)
        self._move = actionlib.ActionClient("move_action", GeneralAction)
        self._goal_handle = None  # keeps the current goal's transitions coming
        self._control = rospy.Publisher("control_cmd", GeneralCmd, queue_size=10)
        self._voice = rospy.Publisher("voice_cmd", VoiceCmd, queue_size=10)
        self._status = rospy.Publisher("charge_status", GeneralTopic, queue_size=10, latch=True)
        self.twin = None  # set once the command twin exists (alarms go out on its ack topic)
        self._last_state = None

    # task_control -------------------------------------------------------------------------------
    def task(self, token, cmd):
        self._task_worker.submit((token, cmd))

    def _call_task(self, request):
        token, cmd = request
        try:
            self._task_proxy.wait_for_service(self._task_timeout)
            reply = self._task_proxy(sender=NODE_NAME, cmd=cmd, data="charge", trans_id=next(self._trans_ids))
        except (rospy.ROSException, rospy.ServiceException) as err:
            self._events.submit(("task", token, None, "%s: %s" % (self._task_service, err)))
            return
        self._events.submit(("task", token, reply.ack == ACK_SUCCESS, reply.data))

    def _refuse_task(self, request):
        self._events.submit(("task", request[0], None, "task_control queue full"))

    # move_action --------------------------------------------------------------------------------
    def goal(self, token, pose, precision, backward):
        # a short wait: this is the event thread; the machine asks again SERVER_RETRY_S later
        if not self._move.wait_for_server(rospy.Duration(SERVER_WAIT_S)):
            self._events.submit(("move", token, None, server_unavailable("move_action", self._move, SERVER_WAIT_S)))
            return
        approach_speed, dock_speed, yaw_speed = self._speeds
        data = move_goal_data(pose[0], pose[1], pose[2], precision=precision, backward=backward,
                              velocity_x=dock_speed if precision or backward else approach_speed,
                              velocity_yaw=yaw_speed)
        goal = GeneralGoal(sender=NODE_NAME, type=MOVE_GOAL_TYPE, data=data, trans_id=next(self._trans_ids))
        finished = []

        def transition(handle):
            if handle.get_comm_state() == actionlib.CommState.DONE and not finished:
                finished.append(True)
                self._on_move_done(token, handle.get_terminal_state(), handle.get_result())
        self._goal_handle = self._move.send_goal(goal, transition_cb=transition)

    def _on_move_done(self, token, state, result):
        if result is None:
            name = actionlib.get_name_of_constant(GoalStatus, state)
            self._events.submit(("move", token, False, "no result (%s)" % (name,)))
            return
        ok = result.ret_code == MOVE_RESULT_SUCCESS and state == GoalStatus.SUCCEEDED
        try:
            reason = json.loads(result.data).get("reason", "")
        except (ValueError, AttributeError):
            reason = result.data
        self._events.submit(("move", token, ok, "ret_code %s: %s" % (result.ret_code, reason)))

    def cancel_goal(self):
        if self._goal_handle is not None:
            self._goal_handle.cancel()

    # relay, voice, alarm, status ----------------------------------------------------------------
    def relay(self, closed):
        cmd = "enable_charge" if closed else "disable_charge"
        rospy.loginfo("%s: control_cmd %s" % (NODE_NAME, cmd))
        self._control.publish(GeneralCmd(sender=NODE_NAME, cmd=cmd, trans_id=next(self._trans_ids)))

    def speak(self, clips):
        msg = VoiceCmd(sender=NODE_NAME, language=self._language, data=list(clips), trans_id=next(self._trans_ids))
        msg.header.stamp = rospy.Time.now()
        self._voice.publish(msg)

    def alarm(self, reason, clips):
        rospy.logerr("%s: charge alarm: %s" % (NODE_NAME, reason))
        if self.twin is not None:
            self.twin.publish_ack(failed("charge alarm: " + reason))
        self.speak(clips)

    def warn(self, text):
        rospy.logwarn_throttle_identical(10.0, "%s: %s" % (NODE_NAME, text))

    def status(self, status):
        if status["state"] != self._last_state:
            rospy.loginfo("%s: %s -> %s (battery %s %%)"
                          % (NODE_NAME, self._last_state, status["state"], status["battery"]))
            self._last_state = status["state"]
        msg = GeneralTopic(sender=NODE_NAME, data=json.dumps(status, sort_keys=True))
        msg.header.stamp = rospy.Time.now()
        self._status.publish(msg)


class ChargeControl(object):
    def __init__(self, config, dock, task_service, task_timeout, speeds, language, rate_hz, owners, data_root):
        self._lock = threading.Lock()
        self._events = RequestWorker(NODE_NAME + ": events", self._handle, self._refuse, EVENT_QUEUE)
        self._ports = RosPorts(self._events, task_service, task_timeout, speeds, language)
        with self._lock:
            self.machine = ChargeMachine(config, dock, self._ports, rospy.get_time)
        self._twin = CommandTwin(_LockedTable(self.machine.command_table(), self._lock), NODE_NAME,
                                 "charge_cmd", "charge_ack", NODE_NAME, busy_when_joystick=False, data_root=data_root)
        self._ports.twin = self._twin

        def on_robot_status(msg):
            if not owners.refusal(ROBOT_STATUS, ROBOT_STATUS, msg):
                self._events.submit(("battery", msg))
        rospy.Subscriber("robot_status", RobotStatus, on_robot_status, queue_size=5)
        rospy.Subscriber("task_status", GeneralTopic, lambda msg: self._events.submit(("task_status", msg)),
                         queue_size=5)
        self._timer = rospy.Timer(rospy.Duration(1.0 / rate_hz), lambda _event: self._events.submit(("tick",)))

    def _handle(self, event):
        kind = event[0]
        with self._lock:
            if kind == "battery":
                battery = battery_from_robot_status(event[1])
                if battery is None:
                    rospy.logwarn_throttle(10.0, "%s: robot_status has stale control_status: battery unknown"
                                           % (NODE_NAME,))
                else:
                    self.machine.on_battery(battery)
            elif kind == "task_status":
                state = _task_state(event[1].data)
                if state is not None:
                    self.machine.on_task_status(state)
            elif kind == "task":
                self.machine.on_task_reply(*event[1:])
            elif kind == "move":
                self.machine.on_move_result(*event[1:])
            else:
                self.machine.tick()

    def _refuse(self, event):
        rospy.logerr_throttle(1.0, "%s: event queue full, dropped a %s event" % (NODE_NAME, event[0]))

    def shutdown(self):
        self._timer.shutdown()


def _task_state(data):
    try:
        state = json.loads(data).get("state")
    except (ValueError, AttributeError):
        state = None
    if not isinstance(state, str):
        rospy.logwarn_throttle(10.0, "%s: task_status without a \"state\" string: %r" % (NODE_NAME, data[:80]))
        return None
    return state


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("charge_control")
    config = ChargeConfig(
        low_level=float(settings.get("~low_level")),
        full_level=float(settings.get("~full_level")),
        retries=int(settings.get("~retries")),
        pause_timeout=float(settings.get("~pause_timeout")),
        relay_timeout=float(settings.get("~relay_timeout")),
        current_timeout=float(settings.get("~current_timeout")),
        current_lost_timeout=float(settings.get("~current_lost_timeout")),
        status_timeout=float(settings.get("~status_timeout")))
    dock = parse_dock(site_param("~dock"))
    speeds = (float(settings.get("~approach_velocity_x")), float(settings.get("~dock_velocity_x")),
              float(settings.get("~velocity_yaw")))
    if min(speeds) <= 0:
        raise ValueError("~approach_velocity_x, ~dock_velocity_x and ~velocity_yaw must be positive")
    language = voice_language(str(settings.get("~voice_language") or ""))   # "": the site's
    if language not in VOICE_LANGUAGES:
        raise ValueError("~voice_language must be one of %s" % (VOICE_LANGUAGES,))
    rate_hz = float(settings.get("~rate"))
    if rate_hz <= 0:
        raise ValueError("~rate must be positive")
    node = ChargeControl(config, dock, str(settings.get("~task_service")),
                         float(settings.get("~task_service_timeout")), speeds, language, rate_hz,
                         OwnerGate.from_param(NODE_NAME), data_root())
    rospy.on_shutdown(node.shutdown)
    rospy.loginfo("%s: dock %s, charge below %.0f %% up to %.0f %%"
                  % (NODE_NAME, dock.pose, config.low_level, config.full_level))
    rospy.spin()
