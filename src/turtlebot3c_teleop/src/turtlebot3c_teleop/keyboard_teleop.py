"""Keyboard teleoperation: the TurtleBot3 key map, per-model limits and a smooth ramp.

Keys (as turtlebot3_teleop): `w`/`x` raise/lower the target linear speed by
one step, `a`/`d` the target angular speed, space or `s` stop at once. The
published speed follows the target by a ramp, so a key press never jerks the
robot; a stop skips the ramp.

Limits come from the robot model (`turtlebot3c_description.models`), never a
fixed burger table: a waffle may go faster and must turn slower than a burger.
Targets are counted in whole steps, so `w` then `x` lands exactly on zero.
"""
import math
import re
from typing import List, NamedTuple, Optional

from turtlebot3c_description.models import RobotModel

# Key presses from standstill to full speed; upstream's burger needs 22 (0.22 / 0.01).
STEPS_TO_FULL_SPEED = 20
# The output moves toward the target by half a step every 0.1 s, as upstream's
# makeSimpleProfile does at 10 Hz: 5 steps per second.
RAMP_STEPS_PER_SECOND = 5.0

MOTION_KEYS = {"w": (1, 0), "x": (-1, 0), "a": (0, 1), "d": (0, -1)}
STOP_KEYS = (" ", "s")
QUIT_KEYS = ("\x03", "\x04")  # Ctrl-C, Ctrl-D: the terminal is raw, so they arrive as bytes


class KeyLimits(NamedTuple):
    model: str
    max_linear: float  # m/s
    max_angular: float  # rad/s
    linear_step: float  # m/s per key press
    angular_step: float  # rad/s per key press


def limits_for_model(model: RobotModel, linear_step: Optional[float] = None,
                     angular_step: Optional[float] = None) -> KeyLimits:
    """The model's speed limits, with steps defaulting to 1/STEPS_TO_FULL_SPEED of them."""
    limits = KeyLimits(
        model=model.name,
        max_linear=model.max_linear_velocity,
        max_angular=model.max_angular_velocity,
        linear_step=linear_step if linear_step is not None else model.max_linear_velocity / STEPS_TO_FULL_SPEED,
        angular_step=angular_step if angular_step is not None else model.max_angular_velocity / STEPS_TO_FULL_SPEED,
    )
    for name in ("linear_step", "angular_step"):
        if not getattr(limits, name) > 0:
            raise ValueError(f"{name} must be positive, got {getattr(limits, name)}")
    return limits


# Arrow and function keys send escape sequences (ESC [ A is "up"): their letters are not keys.
_ESCAPE_SEQUENCE = re.compile(r"\x1b(\[[0-?]*[ -/]*[@-~]|O.|.)?", re.DOTALL)


def split_keys(text: str) -> List[str]:
    """The single key presses in what the terminal sent, escape sequences dropped."""
    return list(_ESCAPE_SEQUENCE.sub("", text))


def is_quit_key(key: str) -> bool:
    return key in QUIT_KEYS


def is_stop_key(key: str) -> bool:
    return key.lower() in STOP_KEYS


def _approach(current: float, target: float, max_change: float) -> float:
    if abs(target - current) <= max_change:
        return target
    return current + math.copysign(max_change, target - current)


class KeyboardTeleop:
    """Targets set by keys, and output speeds that ramp toward them."""

    def __init__(self, limits: KeyLimits):
        self.limits = limits
        self._max_linear_steps = math.ceil(limits.max_linear / limits.linear_step - 1e-9)
        self._max_angular_steps = math.ceil(limits.max_angular / limits.angular_step - 1e-9)
        self._linear_steps = 0
        self._angular_steps = 0
        self.linear = 0.0
        self.angular = 0.0

    @property
    def target_linear(self) -> float:
        value = self._linear_steps * self.limits.linear_step
        return max(-self.limits.max_linear, min(self.limits.max_linear, value))

    @property
    def target_angular(self) -> float:
        value = self._angular_steps * self.limits.angular_step
        return max(-self.limits.max_angular, min(self.limits.max_angular, value))

    def press(self, key: str) -> bool:
        """Apply one key; False when the key means nothing here."""
        key = key.lower()
        if key in STOP_KEYS:
            self.stop()
            return True
        if key not in MOTION_KEYS:
            return False
        linear, angular = MOTION_KEYS[key]
        self._linear_steps = max(-self._max_linear_steps, min(self._max_linear_steps, self._linear_steps + linear))
        self._angular_steps = max(-self._max_angular_steps,
                                  min(self._max_angular_steps, self._angular_steps + angular))
        return True

    def stop(self) -> None:
        """Targets and output to zero at once: a stop does not ramp."""
        self._linear_steps = self._angular_steps = 0
        self.linear = self.angular = 0.0

    def advance(self, dt: float) -> None:
        """Move the output toward the targets by what the ramp allows in `dt` seconds."""
        self.linear = _approach(self.linear, self.target_linear, self.limits.linear_step * RAMP_STEPS_PER_SECOND * dt)
        self.angular = _approach(self.angular, self.target_angular,
                                 self.limits.angular_step * RAMP_STEPS_PER_SECOND * dt)

    def status_line(self) -> str:
        return (f"{self.limits.model}: linear {self.linear:+.3f} m/s (target {self.target_linear:+.3f}, "
                f"max {self.limits.max_linear:.3f})  angular {self.angular:+.2f} rad/s "
                f"(target {self.target_angular:+.2f}, max {self.limits.max_angular:.2f})")


def help_text(limits: KeyLimits, topic: str) -> str:
    return "\n".join([
        f"Drive the TurtleBot3 ({limits.model}) from this terminal; commands go to {topic}.",
        "",
        "        w",
        "    a   s   d",
        "        x",
        "",
        f"w/x : faster/slower forward, {limits.linear_step:.3f} m/s a press (max {limits.max_linear:.3f} m/s)",
        f"a/d : turn more left/right, {limits.angular_step:.2f} rad/s a press (max {limits.max_angular:.2f} rad/s)",
        "space or s : stop",
        "Ctrl-C : stop and quit",
        "",
    ])
