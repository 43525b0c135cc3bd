"""The LDS-02 (LDROBOT LD08) byte stream, and the fixed 360-beam scan made from it.

Packet (47 bytes, little-endian): 0x54, ver_len 0x2C (12 points; 0xEC also
seen), speed (deg/s), start angle (0.01 deg), 12 x {distance mm uint16,
confidence uint8}, end angle (0.01 deg), timestamp, CRC-8 (polynomial 0x4D,
MSB first, init 0) over the first 46 bytes. A packet is trusted only when its
CRC matches and its angular span is plausible for the reported speed; on a bad
byte the parser moves one byte on and looks for the next header.

Angles are the sensor's own, clockwise. A revolution ends when the angle of a
point wraps around.

Why a fixed 360-beam scan: ROBOTIS's noetic ld08_driver publishes one beam per
raw point, so the number of beams and the angle increment change from one
revolution to the next, and the scan starts at whatever angle the first point
had. Consumers that size their buffers from the first scan, or that compare
beam i across scans, get confused. Here every scan has the LDS-01's layout
(beam i at i degrees counter-clockwise from the front, 360 beams), so SLAM,
navigation and anything else see the same geometry whichever LIDAR is fitted;
each beam takes the point nearest its centre, and beams with no point are 0
("no return", below range_min).
"""
import math
import struct
from typing import List, NamedTuple

HEADER = 0x54
VER_LENS = (0x2C, 0xEC)
POINTS_PER_PACKET = 12
PACKET_SIZE = 47
CRC_POLYNOMIAL = 0x4D
BEAMS = 360

# LD08 triangulation geometry (mm): the reported angle is the optics' angle, not the point's.
OFFSET_X = 5.9
OFFSET_Y = -20.14
SLOPE_Y = 0.11923
SAMPLE_RATE = 2300.0  # points per second, bounds a packet's plausible angular span
# A revolution takes 0.1-0.2 s; one whose angle has not wrapped after two seconds of points (a stalled
# motor, a stuck angle, a stream crafted so) is no scan: its points are dropped, so memory stays bounded.
MAX_REVOLUTION_POINTS = int(2 * SAMPLE_RATE)


def _crc8_table(polynomial):
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ polynomial) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return table


CRC_TABLE = _crc8_table(CRC_POLYNOMIAL)


def crc8(data) -> int:
    crc = 0
    for byte in data:
        crc = CRC_TABLE[(crc ^ byte) & 0xFF]
    return crc


class Point(NamedTuple):
    angle: float  # degrees, the sensor's clockwise angle in [0, 360)
    distance: int  # mm, 0 = no measurement
    confidence: int


class Packet(NamedTuple):
    speed: int  # deg/s
    start_angle: int  # 0.01 deg
    end_angle: int
    timestamp: int
    points: tuple  # (distance mm, confidence) x 12


def encode_packet(speed, start_angle, end_angle, points, timestamp=0, ver_len=0x2C) -> bytes:
    """A packet as the LIDAR sends it (for tests and tools), with its CRC."""
    body = struct.pack("<BBHH", HEADER, ver_len, speed, start_angle)
    for distance, confidence in points:
        body += struct.pack("<HB", distance, confidence)
    body += struct.pack("<HH", end_angle, timestamp)
    return body + bytes((crc8(body),))


def decode_packet(data, offset=0) -> Packet:
    speed, start_angle = struct.unpack_from("<HH", data, offset + 2)
    points = tuple(struct.unpack_from("<HB", data, offset + 6 + 3 * i) for i in range(POINTS_PER_PACKET))
    end_angle, timestamp = struct.unpack_from("<HH", data, offset + 42)
    return Packet(speed, start_angle, end_angle, timestamp, points)


def plausible_span(packet: Packet) -> bool:
    span = ((packet.end_angle // 100 - packet.start_angle // 100) + 360) % 360
    return span <= packet.speed * POINTS_PER_PACKET / SAMPLE_RATE * 1.5


def packet_points(packet: Packet) -> List[Point]:
    """The packet's points with their angles, spread evenly from start to end angle."""
    span = (packet.end_angle + 36000 - packet.start_angle) % 36000
    step = span / (POINTS_PER_PACKET - 1) / 100.0
    points = []
    for i, (distance, confidence) in enumerate(packet.points):
        angle = (packet.start_angle / 100.0 + i * step) % 360.0
        points.append(Point(angle, distance, confidence))
    last = points[-1]
    points[-1] = Point((packet.end_angle % 36000) / 100.0, last.distance, last.confidence)
    return points


class Lds02Parser:
    """Feed it bytes as they come; it returns the completed revolutions (lists of Points), plus the
    motor speed of the last packet. Never raises on data, and holds at most one packet's bytes and
    MAX_REVOLUTION_POINTS points between feeds (`overlong_revolutions` counts the revolutions dropped
    for having more)."""

    def __init__(self):
        self._buffer = bytearray()
        self._points = []
        self._last_angle = None
        self.speed = 0
        self.bytes_discarded = 0
        self.crc_errors = 0
        self.implausible_packets = 0
        self.packets_accepted = 0
        self.overlong_revolutions = 0

    def feed(self, data: bytes) -> List[List[Point]]:
        self._buffer.extend(data)
        buffer = self._buffer
        revolutions = []
        position = 0
        while len(buffer) - position >= PACKET_SIZE:
            if buffer[position] != HEADER or buffer[position + 1] not in VER_LENS:
                position += 1
                self.bytes_discarded += 1
                continue
            if crc8(buffer[position:position + PACKET_SIZE - 1]) != buffer[position + PACKET_SIZE - 1]:
                self.crc_errors += 1
                position += 1
                self.bytes_discarded += 1
                continue
            packet = decode_packet(buffer, position)
            if not plausible_span(packet):
                self.implausible_packets += 1
                position += 1
                self.bytes_discarded += 1
                continue
            position += PACKET_SIZE
            self.packets_accepted += 1
            self.speed = packet.speed
            revolutions.extend(self._add(packet_points(packet)))
        del buffer[:position]
        return revolutions

    @property
    def current_points(self) -> List[Point]:
        """The points of the revolution under way (a copy)."""
        return list(self._points)

    @property
    def buffered(self) -> int:
        """Bytes held for the next feed: less than a packet."""
        return len(self._buffer)

    def _add(self, points):
        done = []
        for point in points:
            if self._last_angle is not None and point.angle < self._last_angle - 180.0:
                done.append(self._points)
                self._points = []
            elif len(self._points) >= MAX_REVOLUTION_POINTS:
                self.overlong_revolutions += 1
                self._points = []
            self._points.append(point)
            self._last_angle = point.angle
        return done


def corrected(point: Point):
    """Distance (mm) and counter-clockwise angle (deg) of the point the LD08 saw, its optics' offset removed."""
    x = point.distance + OFFSET_X
    y = point.distance * SLOPE_Y + OFFSET_Y
    shift = math.degrees(math.atan(y / x))
    return math.hypot(x, y), (360.0 - point.angle + shift) % 360.0


def fixed_scan(points, correct_geometry: bool = True):
    """(ranges m, intensities) over 360 beams, beam i at i degrees counter-clockwise."""
    ranges = [0.0] * BEAMS
    intensities = [0.0] * BEAMS
    offsets = [math.inf] * BEAMS
    for point in points:
        if point.distance == 0:
            continue
        if correct_geometry:
            distance, angle = corrected(point)
        else:
            distance, angle = float(point.distance), (360.0 - point.angle) % 360.0
        beam = int(round(angle)) % BEAMS
        offset = abs(((angle - beam) + 180.0) % 360.0 - 180.0)
        if offset < offsets[beam]:
            offsets[beam] = offset
            ranges[beam] = distance / 1000.0
            intensities[beam] = float(point.confidence)
    return ranges, intensities
