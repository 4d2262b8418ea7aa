"""pose_adapter's logic, without ROS: bring a localizer's pose to move_base's pose topic.

Three modes. ``none``: the localizer already publishes what move_base reads (amcl's ``amcl_pose``
named in ``move_base/pose_topic``); the node does nothing. robot.launch always starts the adapter, and
the site file's ``pose_adapter/mode`` switches it on (roslaunch cannot start a node on a value of a
YAML file), so ``none`` is the shipped default. ``topic``: a localizer that already publishes
PoseWithCovarianceStamped in map under another name (amcl's ``amcl_pose``) is republished unchanged
(setting ``move_base/pose_topic`` to that name does the same without a node). ``tf``: a localizer
that only broadcasts the transform ``map`` → ``base_link`` (cartographer, slam_toolbox localization)
is looked up at a fixed rate and published with a configured covariance, since TF carries none. A
lookup that keeps failing publishes nothing: move_base's pose timeout then stops the robot, and the
adapter says which frames it could not join.
"""
import math

from inspection_robot.angles import yaw_from_quaternion

MODE_NONE, MODE_TOPIC, MODE_TF = "none", "topic", "tf"
MODES = (MODE_NONE, MODE_TOPIC, MODE_TF)
# AdapterParams' settings besides the mode, as config/pose_adapter.yaml names them (the node and the site check
# read these; a unit test checks them against the file)
ADAPTER_SETTINGS = ("input_topic", "output_topic", "rate", "map_frame", "base_frame", "sigma_xy", "sigma_yaw",
                    "error_period")


class AdapterParams(object):
    """The adapter's parameters, validated once; a bad one raises ValueError naming it."""

    def __init__(self, mode, input_topic="amcl_pose", output_topic="localization/pose", rate=10.0,
                 map_frame="map", base_frame="base_link", sigma_xy=0.05, sigma_yaw=0.02, error_period=5.0):
        if mode not in MODES:
            raise ValueError("~mode must be one of %s, got %r" % ("|".join(MODES), mode))
        for name, value in (("input_topic", input_topic), ("output_topic", output_topic),
                            ("map_frame", map_frame), ("base_frame", base_frame)):
            if not isinstance(value, str) or not value.strip():
                raise ValueError("~%s must be a non-empty name, got %r" % (name, value))
        if mode == MODE_TOPIC and input_topic == output_topic:
            raise ValueError("~input_topic and ~output_topic are both %r: the adapter would feed itself" % input_topic)
        for name, value in (("rate", rate), ("error_period", error_period)):
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError("~%s must be a positive number, got %r" % (name, value))
        for name, value in (("sigma_xy", sigma_xy), ("sigma_yaw", sigma_yaw)):
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError("~%s must be a number >= 0, got %r" % (name, value))
        self.mode, self.input_topic, self.output_topic = mode, input_topic, output_topic
        self.rate, self.error_period = float(rate), float(error_period)
        self.map_frame, self.base_frame = map_frame, base_frame
        self.sigma_xy, self.sigma_yaw = float(sigma_xy), float(sigma_yaw)


def planar_covariance(sigma_xy, sigma_yaw):
    """Row-major 6x6 covariance with variance sigma_xy² on x and y and sigma_yaw² on yaw (what
    move_base reads: entries 0, 7, 35); z, roll and pitch stay 0."""
    cov = [0.0] * 36
    cov[0] = cov[7] = float(sigma_xy) ** 2
    cov[35] = float(sigma_yaw) ** 2
    return cov


def pose_from_transform(translation, rotation):
    """(x, y, yaw) of base in map from a transform's (x, y, z) and quaternion (x, y, z, w)."""
    return float(translation[0]), float(translation[1]), yaw_from_quaternion(*rotation)


class LookupWatch(object):
    """Counts failing lookups so the node can say, at most every ``period`` s, how long the frames
    have not been joined; a success resets it."""

    def __init__(self, map_frame, base_frame, period):
        self.frames = "%s -> %s" % (map_frame, base_frame)
        self.period = float(period)
        self.failing_since = None
        self._last_report = None

    def succeeded(self):
        recovered = self.failing_since is not None
        self.failing_since = self._last_report = None
        return recovered

    def failed(self, now, reason):
        """The error to log now (or None: reported recently)."""
        if self.failing_since is None:
            self.failing_since = now
        if self._last_report is not None and now - self._last_report < self.period:
            return None
        self._last_report = now
        return ("cannot look up transform %s for %.1f s (%s): publishing no pose, so move_base stops "
                "the robot on its pose timeout" % (self.frames, now - self.failing_since, reason))
