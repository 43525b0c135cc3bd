"""Differential-drive odometry from the OpenCR wheel encoders, with midpoint integration.

Heading comes from the IMU when the board gives a valid orientation (as the
TurtleBot3 firmware and turtlebot3_node do), from the wheels otherwise. The
odometry never jumps: after a reconnection, a board reset, or an encoder step
no wheel could have made, the next reading only becomes the new baseline.
"""
import math
from typing import NamedTuple, Optional

from turtlebot3c_bringup.opencr_control_table import TICK_TO_RAD
from turtlebot3c_common.se2 import wrap_angle

INT32_RANGE = 1 << 32


class Pose2D(NamedTuple):
    x: float
    y: float
    yaw: float


def tick_delta(current: int, previous: int) -> int:
    """Signed change of an int32 encoder counter, across its wrap-around."""
    delta = (current - previous) % INT32_RANGE
    return delta - INT32_RANGE if delta >= INT32_RANGE // 2 else delta


class Snapshot(NamedTuple):
    """What a restarted driver needs to continue the odometry of the one before it."""
    x: float
    y: float
    yaw: float
    left_wheel: float  # rad, accumulated
    right_wheel: float
    left_ticks: int  # the encoder reading the pose belongs to
    right_ticks: int
    imu_yaw: Optional[float]
    stamp: float  # monotonic clock (system-wide, so comparable across processes)


class WheelOdometry:
    def __init__(self, wheel_radius: float, wheel_separation: float, max_wheel_speed: float,
                 use_imu_yaw: bool = True, plausible_speed_factor: float = 3.0):
        """`max_wheel_speed` (rad/s) bounds what counts as a real movement between two readings."""
        self.wheel_radius = wheel_radius
        self.wheel_separation = wheel_separation
        self.max_plausible_wheel_speed = max_wheel_speed * plausible_speed_factor
        self.use_imu_yaw = use_imu_yaw
        self.pose = Pose2D(0.0, 0.0, 0.0)
        self.linear = 0.0
        self.angular = 0.0
        self.wheel_positions = (0.0, 0.0)  # rad, accumulated since start
        self.discontinuities = 0
        self._last_ticks = None
        self._last_imu_yaw = None
        self._last_stamp = None

    def rebaseline(self):
        """Forget the last reading: the next one is a new start (after a reconnection)."""
        self._last_ticks = None
        self._last_imu_yaw = None
        self._last_stamp = None
        self.linear = 0.0
        self.angular = 0.0

    def reset(self, pose: Optional[Pose2D] = None):
        self.pose = pose or Pose2D(0.0, 0.0, 0.0)
        self.rebaseline()

    def snapshot(self) -> Optional[Snapshot]:
        if self._last_ticks is None:
            return None
        return Snapshot(self.pose.x, self.pose.y, self.pose.yaw, self.wheel_positions[0], self.wheel_positions[1],
                        self._last_ticks[0], self._last_ticks[1], self._last_imu_yaw, self._last_stamp)

    def restore(self, snapshot: Snapshot, same_encoders: bool):
        """Continue from a snapshot: from its encoder reading when the counters are the same ones
        (the board was not reset since), else from its pose only, the next reading being a new baseline."""
        self.pose = Pose2D(snapshot.x, snapshot.y, snapshot.yaw)
        self.wheel_positions = (snapshot.left_wheel, snapshot.right_wheel)
        self.rebaseline()
        if same_encoders:
            self._last_ticks = (snapshot.left_ticks, snapshot.right_ticks)
            self._last_imu_yaw = snapshot.imu_yaw
            self._last_stamp = snapshot.stamp

    def update(self, left_ticks: int, right_ticks: int, stamp: float, imu_yaw: Optional[float] = None) -> bool:
        """Integrate one reading taken at `stamp` (s). False when it only set the baseline."""
        previous_ticks, previous_yaw, previous_stamp = self._last_ticks, self._last_imu_yaw, self._last_stamp
        self._last_ticks = (left_ticks, right_ticks)
        self._last_imu_yaw = imu_yaw
        self._last_stamp = stamp
        if previous_ticks is None or stamp <= previous_stamp:
            return False
        dt = stamp - previous_stamp
        left = tick_delta(left_ticks, previous_ticks[0]) * TICK_TO_RAD
        right = tick_delta(right_ticks, previous_ticks[1]) * TICK_TO_RAD
        if max(abs(left), abs(right)) > self.max_plausible_wheel_speed * max(dt, 0.05):
            # A board reset or a reconnection to a fresh counter: no wheel turns that fast.
            self.discontinuities += 1
            self.linear = self.angular = 0.0
            return False
        distance = self.wheel_radius * (left + right) / 2.0
        if self.use_imu_yaw and imu_yaw is not None and previous_yaw is not None:
            turn = wrap_angle(imu_yaw - previous_yaw)
        else:
            turn = self.wheel_radius * (right - left) / self.wheel_separation
        x, y, yaw = self.pose
        heading = yaw + turn / 2.0
        self.pose = Pose2D(x + distance * math.cos(heading), y + distance * math.sin(heading),
                           wrap_angle(yaw + turn))
        self.wheel_positions = (self.wheel_positions[0] + left, self.wheel_positions[1] + right)
        self.linear = distance / dt
        self.angular = turn / dt
        return True
