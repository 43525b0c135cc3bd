"""Which firmware an OpenCR that does not answer DYNAMIXEL pings runs, and what to tell its owner.

The driver needs ROBOTIS's ROS 2 TurtleBot3 firmware (DYNAMIXEL protocol 2.0, ID
200, 1 Mbps). A board bought for ROS 1 Noetic comes with the rosserial firmware
(115200 baud), which ignores pings: the driver then listens at 115200 for it
(`listen_for_rosserial`) so that the log and `turtlebot3c.status` can name it.
"""
import time
from typing import NamedTuple, Optional

import serial

from turtlebot3c_bringup import rosserial_frames
from turtlebot3c_bringup.serial_errors import DEVICE_ERRORS

ROSSERIAL_BAUD = 115200  # ROBOTIS's ROS 1 firmware: nh.getHardware()->setBaud(115200)
LISTEN_TIME = 2.5  # s; the firmware answers a topic request at once and sends its version every second
REQUEST_PERIOD = 1.0  # s between topic requests while nothing answers (the board may still be booting)
NEEDED = "ROBOTIS's ROS 2 TurtleBot3 firmware (DYNAMIXEL protocol 2.0, ID 200, 1 Mbps)"
FLASH_HINT = ("flash the ROS 2 firmware: sudo snap stop turtlebot3c.core, then ROBOTIS's update.sh "
              "(see docs/user-guide.md#opencr-firmware)")


class OtherFirmware(NamedTuple):
    name: str
    version: Optional[str]  # as the firmware reports it, None if it did not say
    baud: int

    def describe(self) -> str:
        version = f" {self.version}" if self.version else ""
        return f"{self.name}{version} at {self.baud} baud"


def listen_for_rosserial(port_name: str, listen_time: float = LISTEN_TIME, clock=time.monotonic,
                         open_port=serial.Serial) -> Optional[OtherFirmware]:
    """The rosserial firmware if it talks on `port_name` at 115200 baud, else None (also if the port fails)."""
    parser = rosserial_frames.FrameParser()
    version_topic = version = None
    try:
        port = open_port(port_name, ROSSERIAL_BAUD, timeout=0.05)
    except DEVICE_ERRORS:
        return None
    try:
        deadline = clock() + listen_time
        next_request = clock()
        while clock() < deadline and version is None:
            if parser.frames_accepted == 0 and clock() >= next_request:
                port.write(rosserial_frames.REQUEST_TOPICS)
                next_request = clock() + REQUEST_PERIOD
            frames = parser.feed(port.read(256))
            for info in rosserial_frames.topic_infos(frames):
                if info.name.lstrip("/") == "firmware_version":
                    version_topic = info.topic_id
            for item in frames:
                if version_topic is not None and item.topic_id == version_topic:
                    version = rosserial_frames.decode_version_info(item.payload)
        if parser.frames_accepted:
            port.write(rosserial_frames.STOP_SENDING)
    except DEVICE_ERRORS:
        pass
    finally:
        try:
            port.close()
        except DEVICE_ERRORS:
            pass
    if not parser.frames_accepted:
        return None
    return OtherFirmware("ROBOTIS's ROS 1 rosserial firmware", version, ROSSERIAL_BAUD)


def wrong_firmware_message(port_name: str, found: OtherFirmware) -> str:
    return f"the OpenCR on {port_name} runs {found.describe()}; turtlebot3c needs {NEEDED}"
