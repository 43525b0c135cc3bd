"""Velocity commands for the OpenCR: clamped to the model's limits, encoded for the control table."""
from typing import Tuple

from turtlebot3c_bringup.opencr_control_table import encode_velocity_command
from turtlebot3c_description.models import RobotModel


def clamp(value: float, limit: float) -> float:
    if value != value:  # NaN: refuse to move rather than guess
        return 0.0
    return max(-limit, min(limit, value))


def clamp_to_model(model: RobotModel, linear_x: float, angular_z: float) -> Tuple[float, float]:
    return (clamp(linear_x, model.max_linear_velocity), clamp(angular_z, model.max_angular_velocity))


def command_bytes(model: RobotModel, linear_x: float, angular_z: float) -> bytes:
    """The 24 bytes to write at CMD_VELOCITY_START for a commanded Twist."""
    return encode_velocity_command(*clamp_to_model(model, linear_x, angular_z))
