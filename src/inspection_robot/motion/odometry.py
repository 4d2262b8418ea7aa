"""Dead-reckoning odometry (odom -> base_link) from the chassis' measured velocities."""
import math

from inspection_robot.angles import quaternion_from_yaw, wrap_angle


class Odometry(object):
    """Integrates (velocity_x, velocity_yaw) over time with the midpoint heading."""

    def __init__(self):
        self.x = 0.0
        self.y = 0.0
        self.yaw = 0.0
        self.velocity_x = 0.0
        self.velocity_yaw = 0.0

    def update(self, velocity_x, velocity_yaw, dt):
        if dt <= 0.0 or not (math.isfinite(velocity_x) and math.isfinite(velocity_yaw)):
            return
        dt = min(dt, 0.5)  # a stalled loop must not extrapolate a stale velocity for seconds
        mid = self.yaw + 0.5 * velocity_yaw * dt
        self.x += velocity_x * math.cos(mid) * dt
        self.y += velocity_x * math.sin(mid) * dt
        self.yaw = wrap_angle(self.yaw + velocity_yaw * dt)
        self.velocity_x = velocity_x
        self.velocity_yaw = velocity_yaw

    def quaternion(self):
        """(x, y, z, w) of the heading."""
        return quaternion_from_yaw(self.yaw)
