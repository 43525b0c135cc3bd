"""Per-model dimensions and limits of the TurtleBot3 burger, waffle and waffle_pi.

Figures follow the OpenCR firmware and turtlebot3_description: the firmware
clamps wheel speed to 61 rpm (burger) or 77 rpm (waffle, waffle_pi), which
gives the maximum linear speed; the maximum angular speed is that divided by
the turning radius.
"""
import math
from typing import Dict, NamedTuple, Tuple

WHEEL_RADIUS = 0.033  # m, all models


class RobotModel(NamedTuple):
    name: str
    wheel_radius: float  # m
    wheel_separation: float  # m, between wheel contact points
    turning_radius: float  # m, firmware constant for the angular limit
    max_wheel_rpm: float
    robot_radius: float  # m, circle enclosing the footprint
    footprint: Tuple[Tuple[float, float], ...]  # polygon in base_footprint, m
    max_linear_acceleration: float  # m/s^2
    max_angular_acceleration: float  # rad/s^2
    scan_mount: Tuple[float, float, float]  # base_scan origin in base_footprint (x, y, z), m
    imu_mount: Tuple[float, float, float]  # imu_link origin in base_footprint (x, y, z), m

    @property
    def max_linear_velocity(self) -> float:
        return self.wheel_radius * 2.0 * math.pi * self.max_wheel_rpm / 60.0

    @property
    def max_angular_velocity(self) -> float:
        return self.max_linear_velocity / self.turning_radius


MODELS: Dict[str, RobotModel] = {
    "burger": RobotModel(
        name="burger",
        wheel_radius=WHEEL_RADIUS,
        wheel_separation=0.160,
        turning_radius=0.080,
        max_wheel_rpm=61.0,
        robot_radius=0.105,
        footprint=((-0.105, -0.105), (-0.105, 0.105), (0.041, 0.105), (0.041, -0.105)),
        max_linear_acceleration=2.5,
        max_angular_acceleration=3.2,
        scan_mount=(-0.032, 0.0, 0.182),
        imu_mount=(-0.032, 0.0, 0.078),
    ),
    "waffle": RobotModel(
        name="waffle",
        wheel_radius=WHEEL_RADIUS,
        wheel_separation=0.287,
        turning_radius=0.1435,
        max_wheel_rpm=77.0,
        robot_radius=0.220,
        footprint=((-0.205, -0.155), (-0.205, 0.155), (0.077, 0.155), (0.077, -0.155)),
        max_linear_acceleration=2.5,
        max_angular_acceleration=3.2,
        scan_mount=(-0.064, 0.0, 0.132),
        imu_mount=(0.0, 0.0, 0.078),
    ),
}
MODELS["waffle_pi"] = MODELS["waffle"]._replace(name="waffle_pi")

MODEL_NAMES = tuple(MODELS)


def get_model(name: str) -> RobotModel:
    """Return the model called `name`, or raise ValueError naming the known ones."""
    try:
        return MODELS[name]
    except KeyError:
        known = ", ".join(MODEL_NAMES)
        raise ValueError(f"unknown TurtleBot3 model {name!r}; known models: {known}") from None
