"""Joystick to velocity: an axis map scaled to the robot model, a deadman button, mux buttons.

No motion unless the deadman button is held: while it is, every joystick
message gives a velocity (stick deflection times the model's maximum speed
times the axis's scale); when it is let go, one zero velocity follows and
then nothing. Mux buttons choose which velocity source drives the robot, on
the press (not while held), as turtlebot3c's joy_teleop configuration does:
button 0 joy_vel, 1 key_vel, 2 nav_vel, 3 none.
"""
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

from turtlebot3c_description.models import RobotModel

MUX_NONE = "__none"


class AxisMapping(NamedTuple):
    axis: int
    scale: float  # fraction of the model's maximum speed at full deflection, sign flips direction


class JoyTeleopConfig(NamedTuple):
    linear: AxisMapping
    angular: AxisMapping
    deadman_button: int
    mux_buttons: Dict[int, str]  # button index -> mux input to select


DEFAULT_CONFIG = JoyTeleopConfig(
    linear=AxisMapping(axis=1, scale=1.0),
    angular=AxisMapping(axis=0, scale=1.0),
    deadman_button=4,
    mux_buttons={0: "joy_vel", 1: "key_vel", 2: "nav_vel", 3: MUX_NONE},
)


class ConfigError(ValueError):
    pass


def _index(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ConfigError(f"{what} must be a non-negative integer index, got {value!r}")
    return value


def _axis_mapping(value, what: str, default: AxisMapping) -> AxisMapping:
    if value is None:
        return default
    if not isinstance(value, dict) or set(value) - {"axis", "scale"}:
        raise ConfigError(f"{what} must be a mapping with keys 'axis' and 'scale', got {value!r}")
    scale = value.get("scale", default.scale)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not -1.0 <= scale <= 1.0:
        raise ConfigError(f"{what}.scale must be a number in [-1, 1] (fraction of the model's maximum), "
                          f"got {scale!r}")
    return AxisMapping(_index(value.get("axis", default.axis), f"{what}.axis"), float(scale))


def config_from_params(params: dict) -> JoyTeleopConfig:
    """Build a config from ROS parameters (as loaded from config/joy_teleop.yaml), with clear errors."""
    known = {"linear", "angular", "deadman_button", "mux_buttons"}
    unknown = sorted(set(params) - known)
    if unknown:
        raise ConfigError(f"unknown joy_teleop parameters {unknown}; known: {sorted(known)}")
    mux_buttons = DEFAULT_CONFIG.mux_buttons
    if "mux_buttons" in params:
        entries = params["mux_buttons"]
        if not isinstance(entries, list):
            raise ConfigError(f"mux_buttons must be a list of {{button: N, topic: NAME}}, got {entries!r}")
        mux_buttons = {}
        for entry in entries:
            if not isinstance(entry, dict) or set(entry) != {"button", "topic"} or not isinstance(entry["topic"], str):
                raise ConfigError(f"each mux_buttons entry must be {{button: N, topic: NAME}}, got {entry!r}")
            mux_buttons[_index(entry["button"], "mux_buttons.button")] = entry["topic"]
    config = JoyTeleopConfig(
        linear=_axis_mapping(params.get("linear"), "linear", DEFAULT_CONFIG.linear),
        angular=_axis_mapping(params.get("angular"), "angular", DEFAULT_CONFIG.angular),
        deadman_button=_index(params.get("deadman_button", DEFAULT_CONFIG.deadman_button), "deadman_button"),
        mux_buttons=mux_buttons,
    )
    if config.deadman_button in config.mux_buttons:
        raise ConfigError(f"button {config.deadman_button} cannot be both the deadman and a mux button")
    return config


class JoyOutput(NamedTuple):
    velocity: Optional[Tuple[float, float]]  # (linear m/s, angular rad/s) to publish, or None
    select: List[str]  # mux inputs to select, in order


def _pressed(buttons: Sequence[int], index: int) -> bool:
    return index < len(buttons) and bool(buttons[index])


def _axis(axes: Sequence[float], mapping: AxisMapping) -> float:
    value = axes[mapping.axis] if mapping.axis < len(axes) else 0.0
    return max(-1.0, min(1.0, value)) * mapping.scale


class JoyTeleop:
    def __init__(self, config: JoyTeleopConfig, model: RobotModel):
        self.config = config
        self.max_linear = model.max_linear_velocity
        self.max_angular = model.max_angular_velocity
        self._previous_buttons: Sequence[int] = ()
        self._deadman_held = False

    def update(self, axes: Sequence[float], buttons: Sequence[int]) -> JoyOutput:
        select = [topic for button, topic in sorted(self.config.mux_buttons.items())
                  if _pressed(buttons, button) and not _pressed(self._previous_buttons, button)]
        self._previous_buttons = list(buttons)
        held = _pressed(buttons, self.config.deadman_button)
        released = self._deadman_held and not held
        self._deadman_held = held
        if held:
            velocity = (_axis(axes, self.config.linear) * self.max_linear,
                        _axis(axes, self.config.angular) * self.max_angular)
        elif released:
            velocity = (0.0, 0.0)
        else:
            velocity = None
        return JoyOutput(velocity, select)

    def missing_inputs(self, axes: Sequence[float], buttons: Sequence[int]) -> List[str]:
        """Configured axes and buttons this joystick does not have, to warn about."""
        missing = [f"axis {m.axis}" for m in (self.config.linear, self.config.angular) if m.axis >= len(axes)]
        wanted = [self.config.deadman_button] + sorted(self.config.mux_buttons)
        return missing + [f"button {b}" for b in wanted if b >= len(buttons)]
