"""The two TurtleBot3 LIDARs behind one interface: serial settings, scan limits, bytes in, scans out."""
from typing import Dict, List, NamedTuple

from turtlebot3c_bringup import lds01_protocol, lds02_protocol


class Scan(NamedTuple):
    ranges: List[float]  # m, 360 beams counter-clockwise from the front
    intensities: List[float]
    rpm: float  # motor speed, 0 if unknown


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

    def feed(self, data: bytes) -> List[Scan]:
        scans = []
        for revolution in self.parser.feed(data):
            if revolution.packets < self.min_packets:
                self.dropped_revolutions += 1
                continue
            scans.append(Scan(revolution.ranges, revolution.intensities, revolution.rpm))
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

    def __init__(self, correct_geometry: bool = True):
        self.parser = lds02_protocol.Lds02Parser()
        self.correct_geometry = correct_geometry

    def feed(self, data: bytes) -> List[Scan]:
        scans = []
        for points in self.parser.feed(data):
            ranges, intensities = lds02_protocol.fixed_scan(points, self.correct_geometry)
            scans.append(Scan(ranges, intensities, self.parser.speed / 6.0))  # deg/s -> rpm
        return scans

    def counters(self) -> Dict[str, int]:
        return {"bytes discarded": self.parser.bytes_discarded, "packets": self.parser.packets_accepted,
                "crc errors": self.parser.crc_errors, "implausible packets": self.parser.implausible_packets}


LDS_MODELS = {"LDS-01": Lds01, "LDS-02": Lds02}


def make_lds(name: str, **options):
    """The decoder for LIDAR model `name`, or ValueError naming the known ones."""
    try:
        return LDS_MODELS[name](**options)
    except KeyError:
        raise ValueError(f"unknown LIDAR model {name!r}; known models: {', '.join(LDS_MODELS)}") from None
