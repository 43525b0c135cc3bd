"""Byte streams of the TurtleBot3 LIDARs, LDS-01 (HLS-LFCD2) and LDS-02 (LDROBOT LD08), from ray casts.

Both spin at 5 Hz. A stream is asked for the packets due up to a time and
ray-casts each packet's beams at that moment, so a moving robot gives the
same skewed revolution a real spinning LIDAR gives.

LDS-01: 60 packets of 42 bytes per revolution, 6 readings each:
`FA | A0+index | speed (rpm x 10, u16) | 6 x (intensity u16, range mm u16, 2 reserved) | checksum x2`.
Reading k of packet p measures 1-degree beam `359 - (6p + k)` counter-clockwise
(the LIDAR counts clockwise); no return is range 0. The checksum bytes both
hold `(0xFF - sum(bytes 0..39)) & 0xFF` (ROBOTIS's driver does not check them).
Commands from the host: 'b' starts the motor, 'e' stops it; the firmware spins at power-on.

LDS-02: 47-byte packets of 12 points: `54 | 2C | speed (deg/s) | start angle (0.01 deg) |
12 x (distance mm u16, confidence u8) | end angle | timestamp ms | CRC-8 (poly 0x4D)`.
Angles count clockwise, and the sensor measures from a point offset from its
axis; `ld08_correction` is the correction ROBOTIS's driver applies, and this
stream emits the raw (distance, angle) that the correction maps back onto the
true ranges. Here 30 packets of 12 one-degree points make a revolution.
"""
import struct
from typing import Callable

import numpy as np

REVOLUTIONS_PER_SECOND = 5.0
RANGE_MAX = 3.5  # m, beyond which LDS-01 reports no return

LDS01_PACKET_SIZE = 42
LDS01_PACKETS_PER_REVOLUTION = 60
LDS01_READINGS_PER_PACKET = 6
LDS01_INTENSITY = 1000  # a plausible value for any return

LDS02_PACKET_SIZE = 47
LDS02_POINTS_PER_PACKET = 12
LDS02_PACKETS_PER_REVOLUTION = 30
LDS02_CONFIDENCE = 200  # above the driver's low-confidence threshold (92)
LDS02_RANGE_MAX = 8.0  # m, the LD08's reach
LD08_OFFSET_X, LD08_OFFSET_Y = 5.9, -20.14  # mm, the driver's transform constants
LD08_SLOPE = 0.11923
LD08_PI = 3.14159  # the driver's value of pi in its angle shift

RangesAt = Callable[[np.ndarray, float], np.ndarray]  # (angles rad CCW in base_scan, range max) -> m, inf = none


def lds01_checksum(packet: bytes) -> int:
    return (0xFF - sum(packet[:40])) & 0xFF


def _crc8_table():
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x4D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return table


_CRC8 = _crc8_table()


def crc8(data: bytes) -> int:
    crc = 0
    for byte in data:
        crc = _CRC8[(crc ^ byte) & 0xFF]
    return crc


def ld08_correction(distance_mm, angle_deg):
    """ROBOTIS's LD08 driver transform: raw (distance mm, clockwise angle deg) -> (range mm, CCW angle deg)."""
    distance_mm = np.asarray(distance_mm, float)
    x = distance_mm + LD08_OFFSET_X
    y = distance_mm * LD08_SLOPE + LD08_OFFSET_Y
    shift = np.arctan(y / x) * 180.0 / LD08_PI
    return np.hypot(x, y), np.mod((360.0 - np.asarray(angle_deg, float)) + shift, 360.0)


def ld08_raw_distance(range_mm):
    """Inverse of the range part of ld08_correction: the raw distance that corrects to range_mm."""
    range_mm = np.asarray(range_mm, float)
    a = 1.0 + LD08_SLOPE ** 2
    b = 2.0 * (LD08_OFFSET_X + LD08_SLOPE * LD08_OFFSET_Y)
    c = LD08_OFFSET_X ** 2 + LD08_OFFSET_Y ** 2 - range_mm ** 2
    return (-b + np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)


class _PacketClock:
    """Which packet numbers are due by a time, at a fixed packet rate, with a pause while stopped."""

    def __init__(self, packets_per_second: float, start_time: float):
        self.period = 1.0 / packets_per_second
        self._base_time, self._base_index = start_time, 0
        self.next_index = 0

    @property
    def next_time(self) -> float:
        # Computed from a base rather than accumulated, so rounding never drifts the rate.
        return self._base_time + (self.next_index - self._base_index) * self.period

    def due(self, now: float):
        while self.next_time <= now:
            yield self.next_index, self.next_time
            self.next_index += 1

    def restart(self, now: float):
        self._base_time, self._base_index = max(self.next_time, now), self.next_index


class Lds01Stream:
    """The LDS-01's packets; `packets_until(now)` gives the bytes due since the last call."""

    model = "LDS-01"
    packet_size = LDS01_PACKET_SIZE

    def __init__(self, ranges_at: RangesAt, start_time: float = 0.0):
        self._ranges_at = ranges_at
        self._clock = _PacketClock(LDS01_PACKETS_PER_REVOLUTION * REVOLUTIONS_PER_SECOND, start_time)
        self.spinning = True

    def command(self, data: bytes, now: float):
        """Bytes from the host: 'b' starts, 'e' stops; anything else is ignored."""
        for byte in data:
            if byte == ord("b") and not self.spinning:
                self.spinning = True
                self._clock.restart(now)
            elif byte == ord("e"):
                self.spinning = False

    def packets_until(self, now: float):
        """[(packet bytes)] due by `now`."""
        if not self.spinning:
            self._clock.restart(now)
            return []
        return [self.packet(index % LDS01_PACKETS_PER_REVOLUTION) for index, _ in self._clock.due(now)]

    def packet(self, number: int) -> bytes:
        readings = LDS01_READINGS_PER_PACKET * number + np.arange(LDS01_READINGS_PER_PACKET)
        beams = 359 - readings
        ranges = self._ranges_at(np.radians(beams.astype(float)), RANGE_MAX)
        millimetres = np.where(np.isfinite(ranges), np.round(np.minimum(ranges, RANGE_MAX) * 1000.0), 0).astype(int)
        speed = int(round(REVOLUTIONS_PER_SECOND * 60.0 * 10.0))
        body = bytearray(struct.pack("<BBH", 0xFA, 0xA0 + number, speed))
        for millimetre in millimetres:
            body += struct.pack("<HHH", LDS01_INTENSITY if millimetre else 0, int(millimetre), 0)
        checksum = lds01_checksum(body)
        return bytes(body + bytes([checksum, checksum]))


class Lds02Stream:
    """The LDS-02's packets; `packets_until(now)` gives the bytes due since the last call."""

    model = "LDS-02"
    packet_size = LDS02_PACKET_SIZE

    def __init__(self, ranges_at: RangesAt, start_time: float = 0.0):
        self._ranges_at = ranges_at
        self._clock = _PacketClock(LDS02_PACKETS_PER_REVOLUTION * REVOLUTIONS_PER_SECOND, start_time)
        self.spinning = True

    def command(self, data: bytes, now: float):
        """The LD08 takes no commands."""

    def packets_until(self, now: float):
        return [self.packet(index % LDS02_PACKETS_PER_REVOLUTION, time) for index, time in self._clock.due(now)]

    def raw_points(self, device_angles_deg: np.ndarray) -> np.ndarray:
        """Raw distances (mm, 0 = no return) the LD08 reports at its clockwise angles now.

        Where a point lands after the driver's correction depends on its own distance,
        so the true range is found by a few fixed-point iterations.
        """
        base = 360.0 - device_angles_deg
        angles = base.copy()
        distances = np.zeros(len(device_angles_deg))
        for _ in range(3):
            ranges = self._ranges_at(np.radians(angles), LDS02_RANGE_MAX)
            hit = np.isfinite(ranges)
            distances = np.where(hit, ld08_raw_distance(np.where(hit, ranges, 0.0) * 1000.0), 0.0)
            _, corrected = ld08_correction(np.maximum(distances, 1.0), device_angles_deg)
            angles = np.where(hit, corrected, base)
        return np.round(distances).astype(int)

    def packet(self, number: int, time: float = 0.0) -> bytes:
        first = number * LDS02_POINTS_PER_PACKET
        device_angles = (first + np.arange(LDS02_POINTS_PER_PACKET)).astype(float)
        distances = self.raw_points(device_angles)
        speed = int(round(REVOLUTIONS_PER_SECOND * 360.0))
        body = bytearray(struct.pack("<BBHH", 0x54, 0x2C, speed, int(first * 100)))
        for distance in distances:
            body += struct.pack("<HB", int(distance), LDS02_CONFIDENCE if distance else 0)
        end_angle = int((first + LDS02_POINTS_PER_PACKET - 1) * 100) % 36000
        body += struct.pack("<HH", end_angle, int(time * 1000.0) % 30000)
        return bytes(body + bytes([crc8(body)]))


def make_stream(model: str, ranges_at: RangesAt, start_time: float = 0.0):
    streams = {"LDS-01": Lds01Stream, "LDS-02": Lds02Stream}
    try:
        return streams[model](ranges_at, start_time)
    except KeyError:
        raise ValueError(f"unknown LIDAR model {model!r}; known: {', '.join(streams)}") from None


BAUD_RATES = {"LDS-01": 230400, "LDS-02": 115200}  # each LIDAR's serial rate (ROBOTIS's drivers)
