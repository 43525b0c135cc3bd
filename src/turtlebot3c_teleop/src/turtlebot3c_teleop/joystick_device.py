"""The Linux joystick API (`/dev/input/js*`): events in, joystick state out.

Each read of a joystick device gives 8-byte `struct js_event` records in the
machine's byte order: uint32 time (ms), int16 value, uint8 type, uint8 number.
Type 0x01 is a button (value 0 or 1), 0x02 an axis (-32767..32767); 0x80 is
or-ed in for the synthetic events the driver sends on open to report the
initial state. Axis values follow ROS joy_node's convention: scaled to -1..1,
inverted so that stick up and stick left are positive, with a dead zone
around the centre that is cut out and the rest stretched to keep full range.
"""
import struct
from typing import List, NamedTuple, Tuple

JS_EVENT = struct.Struct("=IhBB")
JS_EVENT_BUTTON = 0x01
JS_EVENT_AXIS = 0x02
JS_EVENT_INIT = 0x80
AXIS_FULL_SCALE = 32767.0


class JsEvent(NamedTuple):
    time_ms: int
    value: int
    type: int
    number: int

    @property
    def kind(self) -> int:
        return self.type & ~JS_EVENT_INIT

    @property
    def is_init(self) -> bool:
        return bool(self.type & JS_EVENT_INIT)


def encode_event(event: JsEvent) -> bytes:
    return JS_EVENT.pack(event.time_ms & 0xFFFFFFFF, event.value, event.type, event.number)


def parse_events(data: bytes) -> Tuple[List[JsEvent], bytes]:
    """Whole events in `data`, and the bytes of an incomplete one left for the next read."""
    whole = len(data) - len(data) % JS_EVENT.size
    events = [JsEvent(*fields) for fields in JS_EVENT.iter_unpack(data[:whole])]
    return events, data[whole:]


def scale_axis(raw: int, deadzone: float) -> float:
    if not 0.0 <= deadzone < 1.0:
        raise ValueError(f"deadzone must be in [0, 1), got {deadzone}")
    dead = AXIS_FULL_SCALE * deadzone
    if -dead <= raw <= dead:
        return 0.0
    magnitude = (abs(raw) - dead) / (AXIS_FULL_SCALE - dead)
    value = -min(1.0, magnitude) if raw > 0 else min(1.0, magnitude)
    return value + 0.0  # no -0.0


class JoystickState:
    """Axes (-1..1) and buttons (0/1) as the events so far describe them."""

    def __init__(self, deadzone: float = 0.05):
        scale_axis(0, deadzone)  # validates
        self.deadzone = deadzone
        self.axes: List[float] = []
        self.buttons: List[int] = []

    def apply(self, event: JsEvent) -> bool:
        """Update from one event; True when a published value changed."""
        if event.kind == JS_EVENT_BUTTON:
            return _set_growing(self.buttons, event.number, 1 if event.value else 0, 0)
        if event.kind == JS_EVENT_AXIS:
            return _set_growing(self.axes, event.number, scale_axis(event.value, self.deadzone), 0.0)
        return False

    def released(self) -> Tuple[List[float], List[int]]:
        """Every axis centred and every button up: what to report when the device goes away."""
        return [0.0] * len(self.axes), [0] * len(self.buttons)


def _set_growing(values: list, index: int, value, fill) -> bool:
    grown = index >= len(values)
    if grown:
        values.extend([fill] * (index + 1 - len(values)))
    changed = grown or values[index] != value
    values[index] = value
    return changed
