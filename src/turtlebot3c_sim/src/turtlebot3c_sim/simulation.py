"""Kinematic TurtleBot3 simulation: differential drive, wheel odometry, IMU and LIDAR.

The robot follows its velocity command within the model's limits, changing
speed no faster than the model's accelerations. A step that would make the
footprint overlap an obstacle is cut short at the contact (found by
bisection) and the robot stops there: `in_contact` is set, `collided` stays
set until `clear_collision()`, and `collisions` counts contacts.

Sensors follow the real robot: wheel encoders see the wheels turn (including
slip, which the ground does not see), the IMU's heading drifts slowly, and
odometry integrates encoder distance with IMU heading as the OpenCR driver
does (along exact arcs rather than the driver's midpoint rule), starting at
the initial world pose (as Gazebo's `odometrySource world`). Each noise source has its own random stream derived
from the seed, so the same seed and the same commands and steps give the same
run, and taking more or fewer scans does not change the motion.
"""
import math
from typing import NamedTuple, Tuple

import numpy as np

from turtlebot3c_common.se2 import wrap_angle
from turtlebot3c_description.models import get_model

from .world import World

SCAN_BEAMS = 360
SCAN_RANGE_MIN = 0.12
SCAN_RANGE_MAX = 3.5
SCAN_RATE = 5.0  # Hz, LDS-01 and Gazebo
GRAVITY = 9.80665
MAX_SUBSTEP = 0.02  # s; longer steps are split so accelerations and contacts stay accurate
CONTACT_BISECTIONS = 8
CLEARANCE_MARGIN = 0.5  # m; obstacles are checked again after the footprint may have moved this far


class NoiseConfig(NamedTuple):
    """Sensor and odometry noise. Variances of odometry errors grow with the motion, not with time,
    so they do not depend on the step size.
    """
    scan_range_std: float = 0.01  # m, Gaussian noise on each range (Gazebo's LDS: 0.01)
    odom_linear_drift: float = 0.01  # m per sqrt(m) travelled by each wheel, random encoder error
    odom_angular_drift: float = 0.01  # rad per sqrt(rad turned + m travelled), IMU heading random walk
    wheel_slip: float = 0.005  # mean fraction of wheel rotation lost to slip (encoders over-read)
    imu_gyro_std: float = 0.002  # rad/s, noise on each angular velocity reading
    imu_accel_std: float = 0.02  # m/s^2, noise on each acceleration reading

    @classmethod
    def none(cls) -> "NoiseConfig":
        """Perfect sensors and odometry."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class Scan(NamedTuple):
    """One LIDAR revolution in the base_scan frame: beam i at angle_min + i * angle_increment, CCW."""
    angle_min: float
    angle_increment: float
    ranges: np.ndarray  # m; np.inf where nothing is within range_max
    range_min: float
    range_max: float
    time: float = 0.0  # simulated time of the scan, s

    @property
    def angle_max(self) -> float:
        return self.angle_min + (len(self.ranges) - 1) * self.angle_increment

    @property
    def angles(self) -> np.ndarray:
        return self.angle_min + np.arange(len(self.ranges)) * self.angle_increment


class Imu(NamedTuple):
    """IMU reading in imu_link (aligned with base_footprint)."""
    orientation_yaw: float  # rad, in the world frame, drifting
    angular_velocity_z: float  # rad/s
    linear_acceleration_x: float  # m/s^2
    linear_acceleration_y: float
    linear_acceleration_z: float
    angular_velocity_x: float = 0.0
    angular_velocity_y: float = 0.0

    @property
    def orientation_quaternion(self) -> Tuple[float, float, float, float]:
        """(w, x, y, z) of a rotation by orientation_yaw about z."""
        half = self.orientation_yaw / 2.0
        return (math.cos(half), 0.0, 0.0, math.sin(half))


def _ramp(current: float, target: float, max_acceleration: float, dt: float) -> Tuple[float, float]:
    """Velocity after moving towards `target` at no more than max_acceleration for dt, and its exact integral."""
    gap = target - current
    if abs(gap) <= max_acceleration * dt:
        reach = abs(gap) / max_acceleration if max_acceleration > 0 else 0.0
        return target, 0.5 * (current + target) * reach + target * (dt - reach)
    new = current + math.copysign(max_acceleration * dt, gap)
    return new, 0.5 * (current + new) * dt


def _arc(x, y, yaw, distance, rotation):
    """Pose after moving `distance` along an arc turning by `rotation` (exact for constant velocities)."""
    if abs(rotation) < 1e-9:
        return x + distance * math.cos(yaw), y + distance * math.sin(yaw), yaw
    radius = distance / rotation
    new_yaw = yaw + rotation
    return (x + radius * (math.sin(new_yaw) - math.sin(yaw)),
            y - radius * (math.cos(new_yaw) - math.cos(yaw)),
            new_yaw)


class Simulation:
    """One robot in one world, advanced by `step(dt)`."""

    def __init__(self, world: World, model: str = "burger", pose=None, seed: int = 0, noise: NoiseConfig = None):
        self.world = world
        self.model = get_model(model)
        self.noise = NoiseConfig() if noise is None else noise
        streams = np.random.SeedSequence(seed).spawn(3)
        self._motion_random = np.random.default_rng(streams[0])
        self._scan_random = np.random.default_rng(streams[1])
        self._imu_random = np.random.default_rng(streams[2])
        x, y, yaw = world.spawn_pose if pose is None else pose
        self._x, self._y, self._yaw = float(x), float(y), wrap_angle(float(yaw))
        self._footprint = np.asarray(self.model.footprint, float)
        self._footprint_radius = float(np.hypot(self._footprint[:, 0], self._footprint[:, 1]).max())
        self._free_motion = 0.0  # how far the footprint may still move without any obstacle check
        if self.footprint_collides(self._x, self._y, self._yaw):
            raise ValueError(f"start pose ({x:.3f}, {y:.3f}, {yaw:.3f}) overlaps an obstacle in {world.name}")
        self.time = 0.0
        self._command = (0.0, 0.0)
        self.command_since = 0.0  # simulated time the command last changed
        self._linear = 0.0
        self._angular = 0.0
        self._acceleration = 0.0
        self._wheels = [0.0, 0.0]  # encoder angles, rad
        self._wheel_rates = (0.0, 0.0)
        self._imu_yaw = self._yaw
        self._odom = [self._x, self._y, self._yaw]
        self._odom_velocity = (0.0, 0.0)
        self.in_contact = False
        self.collided = False
        self.collisions = 0

    # --- commands and time -----------------------------------------------------------

    def set_command(self, linear_x: float, angular_z: float):
        """Velocity command (m/s, rad/s), clamped to the model's limits."""
        max_linear, max_angular = self.model.max_linear_velocity, self.model.max_angular_velocity
        linear = 0.0 if not math.isfinite(linear_x) else max(-max_linear, min(max_linear, float(linear_x)))
        angular = 0.0 if not math.isfinite(angular_z) else max(-max_angular, min(max_angular, float(angular_z)))
        self._command_with((linear, angular))

    @property
    def command(self) -> Tuple[float, float]:
        return self._command

    def stop(self):
        """Command zero velocity (the robot still decelerates within its limits)."""
        self._command_with((0.0, 0.0))

    def _command_with(self, command):
        if command != self._command:
            self._command, self.command_since = command, self.time

    def step(self, dt: float):
        """Advance the simulation by dt seconds."""
        if dt < 0:
            raise ValueError("dt must not be negative")
        substeps = max(1, int(math.ceil(dt / MAX_SUBSTEP - 1e-9)))
        for _ in range(substeps):
            self._substep(dt / substeps)

    def _substep(self, dt):
        if dt == 0.0:
            return
        previous_linear = self._linear
        self._linear, distance = _ramp(self._linear, self._command[0], self.model.max_linear_acceleration, dt)
        self._angular, rotation = _ramp(self._angular, self._command[1], self.model.max_angular_acceleration, dt)
        fraction = self._move(distance, rotation)
        if fraction < 1.0:
            distance, rotation = distance * fraction, rotation * fraction
            self._linear = self._angular = 0.0
        self._acceleration = (self._linear - previous_linear) / dt
        self._sense_motion(distance, rotation, dt)
        self.time += dt

    def _move(self, distance, rotation) -> float:
        """Move along the arc, or as far along it as the obstacles allow; the fraction done."""
        if distance == 0.0 and rotation == 0.0:
            return 1.0
        target = _arc(self._x, self._y, self._yaw, distance, rotation)
        # No footprint point moves further than this, so far from obstacles no check is needed.
        motion = abs(distance) + abs(rotation) * self._footprint_radius
        if motion < self._free_motion:
            self._free_motion -= motion
            self._place(target, contact=False)
            return 1.0
        self._free_motion = self.world.polygon_clearance(self.footprint_at(*target), CLEARANCE_MARGIN)
        if self._free_motion > 0.0:
            self._place(target, contact=False)
            return 1.0
        free, blocked = 0.0, 1.0
        if self._step_blocked(*_arc(self._x, self._y, self._yaw, distance / 2 ** CONTACT_BISECTIONS,
                                    rotation / 2 ** CONTACT_BISECTIONS)):
            blocked = 0.0  # pushing against the obstacle: not even the smallest step is free
        while blocked - free > 1.0 / 2 ** CONTACT_BISECTIONS:
            middle = (free + blocked) / 2.0
            if self._step_blocked(*_arc(self._x, self._y, self._yaw, distance * middle, rotation * middle)):
                blocked = middle
            else:
                free = middle
        self._place(_arc(self._x, self._y, self._yaw, distance * free, rotation * free), contact=True)
        return free

    def _place(self, pose, contact):
        self._x, self._y, self._yaw = pose[0], pose[1], wrap_angle(pose[2])
        if contact and not self.in_contact:
            self.collisions += 1
        if contact:
            self.collided = True
        self.in_contact = contact

    def teleport(self, x: float, y: float, yaw: float):
        """Move the robot (ground truth only; odometry and encoders do not notice) and stop it."""
        if self.footprint_collides(x, y, yaw):
            raise ValueError(f"pose ({x:.3f}, {y:.3f}, {yaw:.3f}) overlaps an obstacle in {self.world.name}")
        self._x, self._y, self._yaw = float(x), float(y), wrap_angle(float(yaw))
        self._linear = self._angular = 0.0
        self._free_motion = 0.0
        self.in_contact = False

    def clear_collision(self):
        self.collided = False

    def _step_blocked(self, x, y, yaw):
        # Steps are short (MAX_SUBSTEP) and start from a free pose, so the boundary test suffices.
        return self.world.polygon_boundary_touches(self.footprint_at(x, y, yaw))

    def footprint_collides(self, x: float, y: float, yaw: float) -> bool:
        return self.world.polygon_collides(self.footprint_at(x, y, yaw))

    def footprint_at(self, x: float, y: float, yaw: float) -> np.ndarray:
        c, s = math.cos(yaw), math.sin(yaw)
        return self._footprint @ np.array([[c, s], [-s, c]]) + (x, y)

    # --- sensors driven by motion ---------------------------------------------------

    def _sense_motion(self, distance, rotation, dt):
        noise, radius = self.noise, self.model.wheel_radius
        half_separation = self.model.wheel_separation / 2.0
        ground = (distance - rotation * half_separation, distance + rotation * half_separation)
        measured = []
        for travel in ground:
            slip = abs(self._motion_random.normal(0.0, noise.wheel_slip * math.sqrt(math.pi / 2.0))) \
                if noise.wheel_slip else 0.0
            error = self._motion_random.normal(0.0, noise.odom_linear_drift * math.sqrt(abs(travel))) \
                if noise.odom_linear_drift and travel else 0.0
            measured.append(travel * (1.0 + slip) + error)
        for index in range(2):
            self._wheels[index] += measured[index] / radius
        self._wheel_rates = (measured[0] / radius / dt, measured[1] / radius / dt)
        heading_error = self._motion_random.normal(
            0.0, noise.odom_angular_drift * math.sqrt(abs(rotation) + abs(distance))) \
            if noise.odom_angular_drift and (rotation or distance) else 0.0
        imu_rotation = rotation + heading_error
        self._imu_yaw = wrap_angle(self._imu_yaw + imu_rotation)
        odom_distance = (measured[0] + measured[1]) / 2.0
        x, y, yaw = _arc(*self._odom, odom_distance, imu_rotation)
        self._odom = [x, y, wrap_angle(yaw)]
        self._odom_velocity = (odom_distance / dt, imu_rotation / dt)

    # --- state ---------------------------------------------------------------------

    @property
    def pose(self) -> Tuple[float, float, float]:
        """Ground truth (x, y, yaw) of base_footprint in the world frame."""
        return (self._x, self._y, self._yaw)

    @property
    def velocity(self) -> Tuple[float, float]:
        """Ground truth (linear, angular) velocity."""
        return (self._linear, self._angular)

    @property
    def odometry(self) -> Tuple[float, float, float, float, float]:
        """Wheel odometry estimate (x, y, yaw, linear, angular); starts at the initial world pose."""
        return (self._odom[0], self._odom[1], self._odom[2], self._odom_velocity[0], self._odom_velocity[1])

    def reset_odometry(self, pose=(0.0, 0.0, 0.0)):
        self._odom = [float(pose[0]), float(pose[1]), float(pose[2])]

    @property
    def wheel_positions(self) -> Tuple[float, float]:
        """Encoder angles (left, right) in rad, as the wheel encoders count them."""
        return (self._wheels[0], self._wheels[1])

    @property
    def wheel_velocities(self) -> Tuple[float, float]:
        """Encoder rates (left, right) in rad/s over the last step."""
        return self._wheel_rates

    def scan_pose(self) -> Tuple[float, float, float]:
        """World pose of base_scan."""
        mount_x, mount_y, _ = self.model.scan_mount
        c, s = math.cos(self._yaw), math.sin(self._yaw)
        return (self._x + c * mount_x - s * mount_y, self._y + s * mount_x + c * mount_y, self._yaw)

    def scan(self, beams: int = SCAN_BEAMS, range_max: float = SCAN_RANGE_MAX) -> Scan:
        """A LIDAR revolution taken now, in base_scan, with Gaussian range noise."""
        increment = 2.0 * math.pi / beams
        ranges = self.scan_ranges(np.arange(beams) * increment, range_max)
        return Scan(0.0, increment, ranges, SCAN_RANGE_MIN, range_max, self.time)

    def scan_ranges(self, angles, range_max: float = SCAN_RANGE_MAX) -> np.ndarray:
        """Noisy ranges now along `angles` (rad, CCW in base_scan); np.inf for no return."""
        x, y, yaw = self.scan_pose()
        angles = np.asarray(angles, float)
        ranges = self.world.raycast(x, y, yaw + angles, range_max)
        if self.noise.scan_range_std:
            noisy = ranges + self._scan_random.normal(0.0, self.noise.scan_range_std, ranges.shape)
            ranges = np.where(np.isfinite(ranges), np.maximum(noisy, 0.0), np.inf)
        return ranges

    def imu(self) -> Imu:
        """An IMU reading now: drifting heading, noisy gyro and accelerometer (centripetal in y)."""
        noise = self.noise
        gyro = self._angular + (self._imu_random.normal(0.0, noise.imu_gyro_std) if noise.imu_gyro_std else 0.0)
        accel = self._imu_random.normal(0.0, noise.imu_accel_std, 3) if noise.imu_accel_std else np.zeros(3)
        return Imu(self._imu_yaw, gyro,
                   self._acceleration + accel[0],
                   self._linear * self._angular + accel[1],
                   GRAVITY + accel[2])
