"""Which LIDAR is really on the port, when the one `lds-model` names gives no scans.

The LDS-01 streams 42-byte packets at 230400 baud, the LDS-02 47-byte packets at
115200: with the wrong model set, the driver reads noise at the wrong rate and
publishes nothing. After a few seconds without a scan it listens with the other
model's rate and parser (`listen_for`), and if that one decodes packets, it names
the model and the `snap set` that fixes it.
"""
import time
from typing import List, NamedTuple

import serial

from turtlebot3c_bringup.lds_models import LDS_MODELS, make_lds
from turtlebot3c_bringup.serial_errors import DEVICE_ERRORS

SILENCE_BEFORE_CHECK = 3.0  # s without a scan (the port open) before another model is tried
LISTEN_TIME = 1.5  # s; either LIDAR sends several packets in a tenth of a second
CHECK_INTERVAL = 30.0  # s between checks while scans stay away (and between repeats of the error)
PACKETS_NEEDED = 10  # valid packets that make a model certain (noise passes a checksum only by chance)


class WrongModel(NamedTuple):
    configured: str
    found: str
    port: str

    @property
    def message(self) -> str:
        return (f"no scans: the LIDAR on {self.port} streams {self.found} packets, "
                f"but lds-model is {self.configured}")

    @property
    def fix(self) -> str:
        return f"sudo snap set turtlebot3c lds-model={self.found}"


def other_models(configured: str) -> List[str]:
    return [name for name in LDS_MODELS if name != configured]


def listen_for(port_name: str, model: str, listen_time: float = LISTEN_TIME, clock=time.monotonic,
               open_port=serial.Serial) -> bool:
    """Whether `model`'s packets come in on `port_name` at that model's baud rate."""
    lds = make_lds(model)
    try:
        port = open_port(port_name, lds.baud, timeout=0.05)
    except DEVICE_ERRORS:
        return False
    try:
        if lds.on_open:
            port.write(lds.on_open)  # an LDS-01 that was stopped starts turning
        deadline = clock() + listen_time
        while clock() < deadline and lds.counters()["packets"] < PACKETS_NEEDED:
            lds.feed(port.read(512))
    except DEVICE_ERRORS:
        return False
    finally:
        try:
            port.close()
        except DEVICE_ERRORS:
            pass
    return lds.counters()["packets"] >= PACKETS_NEEDED
