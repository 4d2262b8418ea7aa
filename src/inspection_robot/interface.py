"""The spec's constants (INTERFACE.md sections 2-4): modes, bit masks, command names, units.

One source of truth: every node and module imports these instead of repeating literals.
"""

# --- common -------------------------------------------------------------------------------
ACK_SUCCESS = "success"
ACK_FAILED = "failed"
BUSY = "busy"              # data of a refused request while the joystick holds the robot
UNSUPPORTED = "unsupported"

SENDER_SERVER = "server"
SENDER_JOY = "joy_control"
SENDER_MOVE_BASE = "move_base"

# --- modes (ControlStatus.mode, RobotStatus.mode) ------------------------------------------
MODE_TASK = 0
MODE_SERVER = 1
MODE_JOY = 2
MODE_NAMES = {MODE_TASK: "task", MODE_SERVER: "server", MODE_JOY: "joy"}
# mode_cmd: cmd acquire (data joy|server) or release; the sender that owns each mode's move_cmd.
MODE_CMD_ACQUIRE = "acquire"
MODE_CMD_RELEASE = "release"
MODE_BY_ACQUIRE_DATA = {MODE_NAMES[MODE_JOY]: MODE_JOY, MODE_NAMES[MODE_SERVER]: MODE_SERVER}   # data: the mode's name
MOVE_SENDER_BY_MODE = {MODE_TASK: SENDER_MOVE_BASE, MODE_SERVER: SENDER_SERVER, MODE_JOY: SENDER_JOY}

# --- MoveCmd units ---------------------------------------------------------------------------
MOVE_VELOCITY_X_UNIT_M_S = 0.001
MOVE_VELOCITY_YAW_UNIT_RAD_S = 0.001
WHEEL_STRAIGHT = 0
WHEEL_STEER = 1

# --- wheel_status ----------------------------------------------------------------------------
WHEEL_STRAIGHT_MODE = 1 << 0
WHEEL_STEER_MODE = 1 << 1
WHEEL_SWITCHING = 1 << 2
WHEEL_STEPPER_FAULT_CLEAR = 1 << 3
WHEEL_SERVO_FAULT_CLEAR = 1 << 4
WHEEL_OBSTACLE_OFF = 1 << 5
WHEEL_COLLISION_OFF = 1 << 6
WHEEL_FALL_OFF = 1 << 7

# --- light_status ----------------------------------------------------------------------------
LIGHT_CHARGE_RELAY = 1 << 0
LIGHT_RED = 1 << 1
LIGHT_GREEN = 1 << 2
LIGHT_BLUE = 1 << 3
LIGHT_SOFT_ESTOP = 1 << 4
LIGHT_HARD_ESTOP = 1 << 5
LIGHT_BUMPER = 1 << 6

# --- stop_status -----------------------------------------------------------------------------
STOP_FRONT_COLLISION = 1 << 0
STOP_OBSTACLE = 1 << 5
STOP_LEFT_FALL = 1 << 6
STOP_RIGHT_FALL = 1 << 7

# --- circuit_status --------------------------------------------------------------------------
CIRCUIT_STEPPER_COMM = 1 << 0
CIRCUIT_JOY_COMM_LOST = 1 << 1
CIRCUIT_JOY_LINE = 1 << 2
CIRCUIT_SENSOR_BOARD_LINE = 1 << 3
CIRCUIT_COLLISION_LINE = 1 << 4
CIRCUIT_LEFT_TOF_LINE = 1 << 5
CIRCUIT_RIGHT_TOF_LINE = 1 << 6
CIRCUIT_BATTERY_CRITICAL = 1 << 7

# --- battery_status --------------------------------------------------------------------------
BATTERY_UNDER_VOLTAGE = 1 << 0
BATTERY_OVER_VOLTAGE = 1 << 1
BATTERY_LOW_TEMP = 1 << 2
BATTERY_HIGH_TEMP = 1 << 3
BATTERY_CHARGING = 1 << 4
BATTERY_DISCHARGING = 1 << 5
BATTERY_LINE_FAULT = 1 << 7
BATTERY_VOLTAGE_UNIT_V = 0.1
BATTERY_CURRENT_UNIT_A = 0.1

# --- motors ----------------------------------------------------------------------------------
MOTOR_COUNT = 8
MOTOR_NAMES = ("servo_lf", "servo_rf", "servo_rr", "servo_lr",
               "stepper_lf", "stepper_rf", "stepper_rr", "stepper_lr")
SERVO_DISCONNECTED = 1 << 0
SERVO_FAULT = 1 << 4
STEPPER_ERROR = 1 << 0
MOTOR_INFO_DISCONNECTED = 1 << 0
MOTOR_INFO_STEP_LOSS_MOVING = 1 << 1
MOTOR_INFO_STEP_LOSS_TARGET = 1 << 2
MOTOR_INFO_CORRECTING = 1 << 3
MOTOR_INFO_PREVIOUS_SHIFT = 4
MOTOR_INFO_NEEDS_HOMING = 1 << 8
MOTOR_INFO_PREVIOUS_NEEDS_HOMING = 1 << 12
MOTOR_INFO_FAULT_CODE_SHIFT = 16

# --- temperatures ----------------------------------------------------------------------------
TEMPERATURE_COUNT = 13
TEMPERATURE_UNIT_C = 0.1
TEMPERATURE_NOT_SAMPLED = -1000
TEMP_BATTERY = 0
TEMP_SERVO_LF, TEMP_SERVO_RF, TEMP_SERVO_RR, TEMP_SERVO_LR = 1, 2, 3, 4
TEMP_STEPPER_LF, TEMP_STEPPER_RF, TEMP_STEPPER_RR, TEMP_STEPPER_LR = 5, 6, 7, 8
TEMP_IPC = 9
TEMP_MOTION_CARD = 10
TEMP_POD_INSIDE = 11
TEMP_POD_OUTSIDE = 12

# --- navigation (NavStatus.nav_status enable bits, nav_warn alarm bits) ---------------------
NAV_OFF_TRACK = 1 << 0
NAV_LOCALIZATION_LOST = 1 << 1
NAV_OBSTACLE_3D = 1 << 2

# --- sensor_status ---------------------------------------------------------------------------
SENSOR_CAMERA_ALARM = 1 << 0
SENSOR_THERMAL_ALARM = 1 << 1

# --- control_cmd -----------------------------------------------------------------------------
CONTROL_COMMANDS = (
    "enable_collision", "disable_collision", "switch_collision",
    "enable_fallen", "disable_fallen", "switch_fallen",
    "enable_obstacle", "disable_obstacle", "switch_obstacle",
    "enable_charge", "disable_charge",
    "enable_stop", "disable_stop",
    "query_status",
)

# --- imu_cmd ---------------------------------------------------------------------------------
IMU_COMMANDS = ("calibrate", "reset", "query")

# --- move_action / find_scale_action ---------------------------------------------------------
MOVE_GOAL_TYPE = "move"
MOVE_FEEDBACK_PLANNING = "0"
MOVE_FEEDBACK_PLANNED = "1"
MOVE_FEEDBACK_MOVING = "2"
MOVE_FEEDBACK_ALARM = "3"
MOVE_RESULT_SUCCESS = "0"
MOVE_RESULT_PLAN_FAILED = "1"
MOVE_RESULT_LOCALIZATION_LOST = "2"
MOVE_RESULT_BLOCKED = "3"
MOVE_RESULT_CANCELLED = "4"
LOCATION_CMD_SET = "set_location"
LOCATION_INIT_POSE = "init_pose"
LOCATION_LAST_POSE = "last_pose"
VIRTUAL_OBSTACLE_COMMANDS = ("add", "modify", "delete", "query", "clear")

FIND_GOAL_PRE_FIND = "pre_find"
FIND_GOAL_SCALE = "find_scale"
FIND_GOAL_FOREIGN = "find_foreign"
FIND_GOAL_BOTH = "find_both"
FIND_GOAL_TYPES = (FIND_GOAL_PRE_FIND, FIND_GOAL_SCALE, FIND_GOAL_FOREIGN, FIND_GOAL_BOTH)
FIND_FEEDBACK_PRESET_SET = "0"
FIND_FEEDBACK_FINDING = "1"
FIND_RESULT_SUCCESS = "0"
FIND_RESULT_FAILED = "1"
FOREIGN_DETECT_READ = 0
FOREIGN_DETECT_FOREIGN = 1
FOREIGN_DETECT_BOTH = 2
ROI_VALUES_PER_BOX = 8

# --- PTZ (cloud_terrace) ---------------------------------------------------------------------
TERRACE_COMMANDS = (
    "set_pan_angle", "get_pan_angle", "set_tilt_angle", "get_tilt_angle", "set_angle", "get_angle",
    "pan_left", "pan_right", "tilt_up", "tilt_down", "terrace_stop",
    "brush_on", "brush_off", "light_on", "light_off",
)
TERRACE_SPEEDS = ("high_speed", "mid_speed", "low_speed")
ANGLE_CENTI_DEG = 100      # angles travel as integer hundredths of a degree ("12300" = 123.00 deg)

# --- arm -------------------------------------------------------------------------------------
ARM_COMMANDS = (
    "record_orbit", "stop_orbit", "play_orbit", "rotate", "stop_rotate",
    "get_orientation", "set_orientation", "move", "stop_move", "get_position", "set_position",
    "reset",
)

# --- camera ----------------------------------------------------------------------------------
CAMERA_COMMANDS = (
    "set_zoom_level", "get_zoom_level", "capture_picture", "set_focus_mode", "get_focus_mode",
    "get_focus_position", "set_focus_position", "zoom_in", "zoom_out", "focus_far", "focus_near",
    "camera_stop", "set_osd_mode", "set_min_focus_distance", "get_min_focus_distance",
    "set_wdr_level", "get_wdr_level", "set_wdr_mode", "get_wdr_mode",
    "set_exposure_mode", "get_exposure_mode", "set_iris", "get_iris",
)
FOCUS_MODES = ("auto", "manual", "semiauto")
FOCUS_POSITION_MIN = 0x1000
FOCUS_POSITION_MAX = 0xC000
MIN_FOCUS_DISTANCES_CM = (10, 30, 100, 150, 300, 600, 1000, 2000, 65535)
WDR_LEVEL_MIN, WDR_LEVEL_MAX = 0, 100
EXPOSURE_MODES = ("manual", "auto")
IRIS_VALUES = (160, 200, 240, 280, 340, 400, 480, 560, 680, 960, 1100, 1400, 1600, 1900, 2200)

# --- thermal imager --------------------------------------------------------------------------
THERMAL_UNIT = "C"   # the unit of every temperature the robot reports (spec: "Temperatures in °C")
INFRARED_COMMANDS = (
    "save_temperature", "capture_picture", "get_max_temperature", "get_spot_temperature",
    "get_high_temperature", "get_low_temperature", "auto_focus", "set_measure_spot",
)

# The devices' staging services: preset_scale's and find_scale's pictures under a fresh hidden
# staged name (files.staged_name), which they move away at once. The robot's own nodes only: the
# backend surface does not offer them, and camera_control / infrared_control refuse hidden names.
CAMERA_STAGING_SERVICE = "camera_staging"
INFRARED_STAGING_SERVICE = "infrared_staging"

# --- voice -----------------------------------------------------------------------------------
VOICE_LANGUAGES = ("chinese", "english")

# --- commands that only read (the bridge may call them again) ----------------------------------
# Per ControlService service (by its base name), the commands that change nothing: the bridge calls
# one again on a fresh connection when its persistent connection broke after the request was
# written (the node may have received it), which a command that changes something must not risk
# (docs/interface.md, Backend link, "Service calls across a node's restart"). Any other command is
# called again only when its request cannot have reached the node. One list; the bridge imports it.
READ_ONLY_COMMANDS = {
    "file_control": ("list", "stat", "read"),
    "calibration_control": ("get",),
    "task_control": ("query_status", "query_tasks", "query_results", "review_queue", "plan", "routine_list",
                     "schedule_list"),
    "terrace_control": ("get_pan_angle", "get_tilt_angle", "get_angle"),
    "arm_control": ("get_orientation", "get_position"),
    "camera_control": ("get_zoom_level", "get_focus_mode", "get_focus_position", "get_min_focus_distance",
                       "get_wdr_level", "get_wdr_mode", "get_exposure_mode", "get_iris"),
    "infrared_control": ("get_max_temperature", "get_spot_temperature", "get_high_temperature",
                         "get_low_temperature"),
}

# --- interface topics (docs/interface.md, relative names) -------------------------------------
# Every topic of the interface, named in full: bag_recorder subscribes to each by name when it
# starts (not by pattern), so a topic a backend advertises later is recorded from its first message.
# The *_cmd/*_ack pairs of every commanded node; location_cmd has no ack (the spec defines none).
COMMAND_NAMES = ("mode", "control", "imu", "terrace", "arm", "camera", "infrared", "virtual_obstacle", "file",
                 "calibration", "charge", "task", "preset_scale", "read_scale", "voice")
COMMAND_TOPICS = tuple("%s_%s" % (name, kind) for name in COMMAND_NAMES for kind in ("cmd", "ack")) + \
    ("location_cmd", "move_cmd")
# What a backend publishes, with its message type (GeneralCmd unless named): rosbridge_websocket
# advertises these when it starts, so every robot node (and the recorder) is subscribed before the
# first client's first message, which a topic advertised only when a client asks would lose.
BACKEND_TOPIC_TYPES = dict(
    [("%s_cmd" % name, "inspection_robot/GeneralCmd") for name in COMMAND_NAMES] + [
        ("location_cmd", "inspection_robot/GeneralCmd"), ("move_cmd", "inspection_robot/MoveCmd"),
        ("preset_scale_cmd", "inspection_robot/PresetScaleCmd"), ("read_scale_cmd", "inspection_robot/ReadScaleCmd"),
        ("voice_cmd", "inspection_robot/VoiceCmd"), ("server_status", "inspection_robot/GeneralTopic"),
        ("preset_rotate", "inspection_robot/PresetRotate")])
# The answers to those commands, which rosbridge_websocket subscribes to when it starts and keeps: a
# client's subscribe joins a subscriber already connected to the node that answers, so the ack of
# the command it sends right after is not lost while a new subscriber would still be connecting.
BACKEND_ACK_TYPES = dict(
    [("%s_ack" % name, "inspection_robot/GeneralAck") for name in COMMAND_NAMES] + [
        ("preset_scale_ack", "inspection_robot/PresetScaleAck"), ("read_scale_ack", "inspection_robot/ReadScaleAck")])
ACTION_NAMES = ("move_action", "find_scale_action", "task_action")
ACTION_TOPICS = ("goal", "cancel", "status", "feedback", "result")   # actionlib's topics of each action
INTERFACE_TOPICS = (
    "server_status", "preset_rotate",                                 # published only by a backend
    "robot_status", "control_status", "nav_status", "robot_odom", "odom", "tf", "tf_static", "diagnostics",
    "obstacle_status", "plan", "map", "virtual_obstacle_map", "virtual_obstacles",
    "task_status", "charge_status", "terrace_state", "camera_zoom", "client_count",
) + COMMAND_TOPICS + tuple("%s/%s" % (a, t) for a in ACTION_NAMES for t in ACTION_TOPICS)
