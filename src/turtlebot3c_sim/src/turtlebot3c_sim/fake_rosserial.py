"""The OpenCR as ROBOTIS's ROS 1 (rosserial) firmware presents it to a host, for the wrong-firmware tests.

Only what a host sees before it would start driving: the board is silent until the
host asks for its topics (a rosserial frame on topic 0 with no payload); it then asks
for the time (topic 10), describes its publishers (topic 0) and subscribers (topic 1)
as rosserial_msgs/TopicInfo, and publishes `firmware_version`
(turtlebot3_msgs/VersionInfo: hardware, firmware, software) once a second until the
host sends tx-stop (topic 11). Frame: `FF FE | len u16 | len checksum | topic u16 |
payload | checksum`, checksums 255 - (sum % 256) (rosserial_python's SerialClient).
Topic ids as on the OpenCR (25 subscribers first, so publishers start at 125).
This module does no I/O: `receive(data, now)` and `due(now)` return the bytes to send.
"""
import struct

FIRMWARE_VERSION = "1.2.6"  # FIRMWARE_VER of the ROS 1 turtlebot3 library
BAUD = 115200
VERSION_PERIOD = 1.0  # s
PUBLISHERS = [("sensor_state", "turtlebot3_msgs/SensorState"),
              ("firmware_version", "turtlebot3_msgs/VersionInfo"),
              ("imu", "sensor_msgs/Imu"), ("odom", "nav_msgs/Odometry")]
SUBSCRIBERS = [("cmd_vel", "geometry_msgs/Twist"), ("sound", "turtlebot3_msgs/Sound"),
               ("motor_power", "std_msgs/Bool"), ("reset", "std_msgs/Empty")]
FIRST_PUBLISHER_ID, FIRST_SUBSCRIBER_ID = 125, 100
TOPIC_REQUEST, TOPIC_SUBSCRIBERS, TOPIC_TIME, TOPIC_TX_STOP = 0, 1, 10, 11
BUFFER_SIZE = 1024


def _sum_check(data: bytes) -> int:
    return 255 - sum(data) % 256


def encode(topic: int, payload: bytes = b"") -> bytes:
    size = struct.pack("<H", len(payload))
    body = struct.pack("<H", topic) + payload
    return b"\xff\xfe" + size + bytes([_sum_check(size)]) + body + bytes([_sum_check(body)])


def _ros_string(text: str) -> bytes:
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def topic_info(topic_id: int, name: str, message_type: str) -> bytes:
    return (struct.pack("<H", topic_id) + _ros_string(name) + _ros_string(message_type)
            + _ros_string("0" * 32) + struct.pack("<i", BUFFER_SIZE))


class RosserialFirmware:
    def __init__(self):
        self._pending = b""
        self.configured = False
        self.requests = 0
        self._next_version = 0.0

    def receive(self, data: bytes, now: float) -> bytes:
        """What the board sends back for the host's bytes `data` (anything but whole frames is ignored)."""
        self._pending += data
        reply = b""
        while True:
            start = self._pending.find(b"\xff\xfe")
            if start < 0:
                self._pending = self._pending[-1:]  # may be the first byte of the next frame
                return reply
            if len(self._pending) - start < 8:
                self._pending = self._pending[start:]
                return reply
            frame = self._pending[start:]
            size = struct.unpack_from("<H", frame, 2)[0]
            if frame[4] != _sum_check(frame[2:4]):
                self._pending = frame[1:]
                continue
            if len(frame) < 8 + size:
                self._pending = frame
                return reply
            topic = struct.unpack_from("<H", frame, 5)[0]
            self._pending = frame[8 + size:]
            if frame[7 + size] != _sum_check(frame[5:7 + size]):
                continue
            reply += self._handle(topic, now)

    def _handle(self, topic: int, now: float) -> bytes:
        if topic == TOPIC_REQUEST:
            self.requests += 1
            self.configured = True
            self._next_version = now  # its loop publishes the version within the next second
            reply = encode(TOPIC_TIME)
            for index, (name, kind) in enumerate(PUBLISHERS):
                reply += encode(TOPIC_REQUEST, topic_info(FIRST_PUBLISHER_ID + index, name, kind))
            for index, (name, kind) in enumerate(SUBSCRIBERS):
                reply += encode(TOPIC_SUBSCRIBERS, topic_info(FIRST_SUBSCRIBER_ID + index, name, kind))
            return reply
        if topic == TOPIC_TX_STOP:
            self.configured = False
        return b""

    def due(self, now: float) -> bytes:
        """What the board publishes by itself up to `now`."""
        if not self.configured or now < self._next_version:
            return b""
        self._next_version = now + VERSION_PERIOD
        version_id = FIRST_PUBLISHER_ID + [name for name, _ in PUBLISHERS].index("firmware_version")
        payload = _ros_string("0.0.0") + _ros_string(FIRMWARE_VERSION) + _ros_string("0.0.0")
        return encode(version_id, payload)
