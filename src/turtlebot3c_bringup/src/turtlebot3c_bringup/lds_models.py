"""The two TurtleBot3 LIDARs behind one interface: serial settings, scan limits, bytes in, timed scans out.

Timing (sensor_msgs/LaserScan: beam i measured at `stamp + i * time_increment`): both
LIDARs turn clockwise seen from above while the scan counts counter-clockwise, so beam 0
(straight ahead) is the LAST one measured in its revolution and `time_increment` is
negative, -scan_time / 360. `stamp` is when beam 0 was measured: the time the bytes that
complete the revolution arrived, less the bytes that came after them in the same read
(a driver that fell behind reads a backlog at once) and less the time the protocol makes
us wait before we know the revolution is over (LDS-01: the next packet's header; LDS-02:
the rest of the packet holding the wrap-around). ROBOTIS's drivers stamp at the same
moment (when the revolution has been read), but give time_increment a positive sign.
"""
from typing import Dict, Iterator, List, NamedTuple, Tuple

from turtlebot3c_bringup import lds01_protocol, lds02_protocol

BEAMS = 360

class Scan(NamedTuple):
    ranges: List[float]  # m, 360 beams counter-clockwise from the front
    intensities: List[float]
    rpm: float  # motor speed, 0 if unknown
    stamp: float = 0.0  # s, when beam 0 was measured, on the clock of feed()'s `read_time`
    time_increment: float = 0.0  # s from beam i to beam i + 1 (negative: see the module's doc); 0 if unknown
    scan_time: float = 0.0  # s per revolution, 0 if unknown


def _pieces(data: bytes, size: int) -> Iterator[Tuple[int, bytes]]:
    """(bytes left after the piece, piece): the data cut so that each revolution is known with its own end."""
    for start in range(0, len(data), size):
        piece = data[start:start + size]
        yield len(data) - start - len(piece), piece


def _timing(rpm: float, arrival: float, latency_in_revolutions: float):
    """(stamp, time_increment, scan_time) of a revolution whose completing bytes arrived at `arrival`."""
    if rpm <= 0:
        return arrival, 0.0, 0.0
    scan_time = 60.0 / rpm
    return arrival - latency_in_revolutions * scan_time, -scan_time / BEAMS, scan_time


class Lds01:
    """HLS-LFCD2: 230400 baud, motor started by 'b' and stopped by 'e'; limits as ROBOTIS's driver."""

    name = "LDS-01"
    baud = 230400
    on_open = lds01_protocol.START_MOTOR
    on_close = lds01_protocol.STOP_MOTOR
    range_min = 0.12
    range_max = 3.5
    min_packets = lds01_protocol.PACKETS_PER_REVOLUTION // 2  # less than half a turn is not worth publishing

    def __init__(self):
        self.parser = lds01_protocol.Lds01Parser()
        self.dropped_revolutions = 0

    def feed(self, data: bytes, read_time: float = 0.0) -> List[Scan]:
        """Scans completed by `data`, which was read at `read_time` (s)."""
        scans = []
        for left, piece in _pieces(data, lds01_protocol.PACKET_SIZE):
            for revolution in self.parser.feed(piece):
                if revolution.packets < self.min_packets:
                    self.dropped_revolutions += 1
                    continue
                # The LIDAR streams 60 packets a revolution back to back: its byte rate follows the motor.
                bytes_per_second = lds01_protocol.PACKET_SIZE * lds01_protocol.PACKETS_PER_REVOLUTION * \
                    max(revolution.rpm, 1.0) / 60.0
                timing = _timing(revolution.rpm, read_time - left / bytes_per_second,
                                 1.0 / lds01_protocol.PACKETS_PER_REVOLUTION)
                scans.append(Scan(revolution.ranges, revolution.intensities, revolution.rpm, *timing))
        return scans

    def counters(self) -> Dict[str, int]:
        return {"bytes discarded": self.parser.bytes_discarded, "packets": self.parser.packets_accepted,
                "incomplete revolutions": self.parser.revolutions_incomplete,
                "revolutions dropped": self.dropped_revolutions}


class Lds02:
    """LDROBOT LD08: 115200 baud, streams on power-up; rated 0.16-8 m (ROBOTIS e-manual, LDS-02)."""

    name = "LDS-02"
    baud = 115200
    on_open = b""
    on_close = b""
    range_min = 0.16
    range_max = 8.0

    min_span = 180.0  # degrees: less than half a turn (the first, joined midway) is not worth publishing

    def __init__(self, correct_geometry: bool = True):
        self.parser = lds02_protocol.Lds02Parser()
        self.correct_geometry = correct_geometry
        self.dropped_revolutions = 0

    def feed(self, data: bytes, read_time: float = 0.0) -> List[Scan]:
        """Scans completed by `data`, which was read at `read_time` (s).

        The fixed layout's seam is at beam 0, the LD08's own revolution ends where its angle
        wraps; the optics' offset shifts far points up to 7 degrees, so the few beams just
        left of the front may hold points from the start of the revolution, 1 revolution
        earlier than the time model says (see README, "Scan timing").
        """
        scans = []
        for left, piece in _pieces(data, lds02_protocol.PACKET_SIZE):
            for points in self.parser.feed(piece):
                if not points or points[-1].angle - points[0].angle < self.min_span:
                    self.dropped_revolutions += 1
                    continue
                ranges, intensities = lds02_protocol.fixed_scan(points, self.correct_geometry)
                rpm = self.parser.speed / 6.0  # deg/s -> rpm
                packets = max(len(points), 1) / lds02_protocol.POINTS_PER_PACKET
                bytes_per_second = lds02_protocol.PACKET_SIZE * packets * max(rpm, 1.0) / 60.0
                # The revolution ends with the packet holding the wrap-around: about one packet late.
                timing = _timing(rpm, read_time - left / bytes_per_second, 1.0 / packets)
                scans.append(Scan(ranges, intensities, rpm, *timing))
        return scans

    def counters(self) -> Dict[str, int]:
        return {"bytes discarded": self.parser.bytes_discarded, "packets": self.parser.packets_accepted,
                "crc errors": self.parser.crc_errors, "implausible packets": self.parser.implausible_packets,
                "revolutions dropped": self.dropped_revolutions}


LDS_MODELS = {"LDS-01": Lds01, "LDS-02": Lds02}


def make_lds(name: str, **options):
    """The decoder for LIDAR model `name`, or ValueError naming the known ones."""
    try:
        return LDS_MODELS[name](**options)
    except KeyError:
        raise ValueError(f"unknown LIDAR model {name!r}; known models: {', '.join(LDS_MODELS)}") from None
