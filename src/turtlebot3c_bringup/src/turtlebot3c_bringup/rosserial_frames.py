"""Just enough of rosserial's wire format to recognise the ROS 1 OpenCR firmware and read its version.

A Noetic-era OpenCR runs ROBOTIS's rosserial firmware at 115200 baud, not the
DYNAMIXEL-protocol firmware this driver speaks. To say so (rather than "no
answer"), the driver listens for rosserial frames:

    FF FE | length (u16 LE) | length checksum | topic id (u16 LE) | payload | checksum

length checksum = 255 - (length bytes' sum % 256); checksum = 255 - (sum of topic id
and payload bytes % 256). The firmware says nothing until the host asks for its
topics (topic 0 with no payload); it then describes each publisher in a
rosserial_msgs/TopicInfo on topic 0 and each subscriber on topic 1, and
publishes, among others, `firmware_version` (turtlebot3_msgs/VersionInfo) once a second.
"""
import struct
from typing import Iterator, List, NamedTuple, Optional, Tuple

SYNC = b"\xff\xfe"  # sync byte and protocol version 2 (ROS Groovy on, so Noetic's)
HEADER_SIZE = 7  # sync (2), length (2), length checksum (1), topic id (2)
TOPIC_PUBLISHER, TOPIC_SUBSCRIBER, TOPIC_TX_STOP = 0, 1, 11
MAX_PAYLOAD = 2048  # the OpenCR's buffers are 1024 bytes; a larger length is noise


def checksum(data: bytes) -> int:
    return 255 - sum(data) % 256


def frame(topic_id: int, payload: bytes = b"") -> bytes:
    length = struct.pack("<H", len(payload))
    body = struct.pack("<H", topic_id) + payload
    return SYNC + length + bytes([checksum(length)]) + body + bytes([checksum(body)])


REQUEST_TOPICS = frame(TOPIC_PUBLISHER)  # what rosserial_python sends to start a session
STOP_SENDING = frame(TOPIC_TX_STOP)  # ends the session: the firmware goes quiet again


class Frame(NamedTuple):
    topic_id: int
    payload: bytes


class FrameParser:
    """Frames out of a byte stream that may hold anything else; bad frames are skipped byte by byte."""

    def __init__(self):
        self._buffer = b""
        self.frames_accepted = 0

    def feed(self, data: bytes) -> List[Frame]:
        self._buffer += data
        frames = []
        while True:
            start = self._buffer.find(SYNC)
            if start < 0:
                self._buffer = self._buffer[-1:]  # a sync's first byte may end this read
                return frames
            buffer = self._buffer = self._buffer[start:]
            if len(buffer) < HEADER_SIZE:
                return frames
            length = struct.unpack_from("<H", buffer, 2)[0]
            if checksum(buffer[2:4]) != buffer[4] or length > MAX_PAYLOAD:
                self._buffer = buffer[1:]
                continue
            end = HEADER_SIZE + length + 1
            if len(buffer) < end:
                return frames
            body = buffer[5:end - 1]
            if checksum(body) != buffer[end - 1]:
                self._buffer = buffer[1:]
                continue
            self._buffer = buffer[end:]
            self.frames_accepted += 1
            frames.append(Frame(struct.unpack_from("<H", body)[0], body[2:]))


def _strings(payload: bytes, offset: int, count: int) -> Tuple[List[str], int]:
    """`count` ROS strings (u32 length + UTF-8) from `offset`: (strings, offset after them)."""
    strings = []
    for _ in range(count):
        (size,) = struct.unpack_from("<I", payload, offset)
        offset += 4
        if offset + size > len(payload):
            raise ValueError("string runs past the message")
        strings.append(payload[offset:offset + size].decode("utf-8", "replace"))
        offset += size
    return strings, offset


class TopicInfo(NamedTuple):
    topic_id: int
    name: str
    message_type: str


def decode_topic_info(payload: bytes) -> Optional[TopicInfo]:
    """rosserial_msgs/TopicInfo (topic id, name, type, md5, buffer size), or None if it is not one."""
    try:
        (topic_id,) = struct.unpack_from("<H", payload)
        (name, message_type), _ = _strings(payload, 2, 2)
    except (struct.error, ValueError):
        return None
    return TopicInfo(topic_id, name, message_type)


def decode_version_info(payload: bytes) -> Optional[str]:
    """The `firmware` field of a turtlebot3_msgs/VersionInfo (hardware, firmware, software), or None."""
    try:
        (_, firmware, _), _ = _strings(payload, 0, 3)
    except (struct.error, ValueError):
        return None
    return firmware


def topic_infos(frames) -> Iterator[TopicInfo]:
    for item in frames:
        if item.topic_id in (TOPIC_PUBLISHER, TOPIC_SUBSCRIBER) and item.payload:
            info = decode_topic_info(item.payload)
            if info is not None:
                yield info
