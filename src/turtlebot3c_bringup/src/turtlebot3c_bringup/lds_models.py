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
from turtlebot3c_bringup.laser_scan import BEAMS


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
    # Degrees into its next revolution where the LD08 may still measure points of a scan's front:
    # the optics' offset moves points up to 6.8 degrees counter-clockwise.
    lead = 10.0

    def __init__(self, correct_geometry: bool = True):
        self.parser = lds02_protocol.Lds02Parser()
        self.correct_geometry = correct_geometry
        self.dropped_revolutions = 0
        self._finished = []  # (points, rpm, timing) of revolutions waiting for the start of the next

    def feed(self, data: bytes, read_time: float = 0.0) -> List[Scan]:
        """Scans completed by `data`, which was read at `read_time` (s).

        The LD08's revolution ends where its own (clockwise) angle wraps, but the scan's seam is
        at beam 0, straight ahead, and the optics' offset moves points up to 7 degrees: the first
        points of a revolution may land on beams 0-7, which the time model says are measured at
        the END of a scan. Such points are given to the scan before (they were measured right
        after its end), so every beam's time follows stamp + i * time_increment; a scan is
        therefore published once the next revolution is `lead` degrees on (some 6 ms at 5 Hz).
        """
        scans = []
        for left, piece in _pieces(data, lds02_protocol.PACKET_SIZE):
            for points in self.parser.feed(piece):
                rpm = self.parser.speed / 6.0  # deg/s -> rpm
                packets = max(len(points), 1) / lds02_protocol.POINTS_PER_PACKET
                bytes_per_second = lds02_protocol.PACKET_SIZE * packets * max(rpm, 1.0) / 60.0
                # The revolution ends with the packet holding the wrap-around: about one packet late.
                self._finished.append((points, rpm, _timing(rpm, read_time - left / bytes_per_second, 1.0 / packets)))
            while self._finished and (len(self._finished) > 1 or self._next_is_on(self.parser.current_points)):
                points, rpm, timing = self._finished.pop(0)
                following = self._finished[0][0] if self._finished else self.parser.current_points
                scan = self._scan(points, following, rpm, timing)
                if scan is not None:
                    scans.append(scan)
        return scans

    def _next_is_on(self, points) -> bool:
        return bool(points) and points[-1].angle >= self.lead

    def _belongs_to_previous_scan(self, point) -> bool:
        if point.distance == 0 or point.angle >= self.lead:
            return False
        angle = lds02_protocol.corrected(point)[1] if self.correct_geometry else (360.0 - point.angle) % 360.0
        return angle < 180.0

    def _scan(self, points, following, rpm, timing):
        if not points or points[-1].angle - points[0].angle < self.min_span:
            self.dropped_revolutions += 1
            return None
        own = [point for point in points if not self._belongs_to_previous_scan(point)]
        own += [point for point in following if self._belongs_to_previous_scan(point)]
        ranges, intensities = lds02_protocol.fixed_scan(own, self.correct_geometry)
        return Scan(ranges, intensities, rpm, *timing)

    def counters(self) -> Dict[str, int]:
        return {"bytes discarded": self.parser.bytes_discarded, "packets": self.parser.packets_accepted,
                "crc errors": self.parser.crc_errors, "implausible packets": self.parser.implausible_packets,
                "overlong revolutions dropped": self.parser.overlong_revolutions,
                "revolutions dropped": self.dropped_revolutions}


LDS_MODELS = {"LDS-01": Lds01, "LDS-02": Lds02}


def make_lds(name: str, **options):
    """The decoder for LIDAR model `name`, or ValueError naming the known ones."""
    try:
        return LDS_MODELS[name](**options)
    except KeyError:
        raise ValueError(f"unknown LIDAR model {name!r}; known models: {', '.join(LDS_MODELS)}") from None
