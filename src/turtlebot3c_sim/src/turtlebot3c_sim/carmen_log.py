"""Real laser data in the old CARMEN log format (Radish's "corrected" logs). Pure numpy; no rospy.

Each `FLASER n r1 .. rn x y theta odom_x odom_y odom_theta ipc_timestamp hostname logger_timestamp`
line is one scan of a front laser at the robot's origin, facing forward, with the pose a
high-quality offline SLAM estimated for it (the reference). The beams span 180 degrees from
-90 degrees: 1 degree apart for 180/181 beams, half a degree for 360/361 (checked by laying
consecutive scans over each other at their reference poses).

A reading at the scanner's maximum means "no return": SICK scanners write about 81.9 m. A
log's no-return marker is its largest reading when many beams share it exactly; in logs
whose largest reading is a lone real echo (acapulco's 51.25 m), no reading is one.
"""
import glob
import gzip
import math
from typing import List, NamedTuple

import numpy as np

FIELD_OF_VIEW = math.pi
MARKER_SHARE = 1e-3  # a value is a no-return marker when at least this share of readings hold it
SCAN_PERIOD_FALLBACK = 1.0  # s between scans of a log whose timestamps are unusable


class LaserLog(NamedTuple):
    name: str
    stamps: np.ndarray      # (N,) s, increasing
    ranges: np.ndarray      # (N, beams) m; no-return readings are +inf
    reference: np.ndarray   # (N, 3) x, y, theta of each scan in the reference map
    angle_min: float
    angle_increment: float

    @property
    def beams(self):
        return self.ranges.shape[1]

    def travel(self):
        """(N,) m of reference path from the first scan to each."""
        steps = np.hypot(*np.diff(self.reference[:, :2], axis=0).T)
        return np.concatenate(([0.0], np.cumsum(steps)))

    def head(self, count):
        """The first `count` scans as a log of their own."""
        return self.part(slice(count))

    def part(self, scans):
        """The scans at `scans` (a slice, or indices) as a log of their own."""
        return self._replace(stamps=self.stamps[scans], ranges=self.ranges[scans], reference=self.reference[scans])


def read_laser_log(path, name=None):
    """The FLASER scans of a CARMEN log (plain or .gz) as a LaserLog; ValueError if it has none."""
    opener = gzip.open if str(path).endswith(".gz") else open
    rows, poses, stamps = [], [], []
    with opener(path, "rt", errors="replace") as stream:
        for line in stream:
            fields = line.split()
            if not fields or fields[0] != "FLASER":
                continue
            count = int(fields[1])
            rows.append([float(value) for value in fields[2:2 + count]])
            poses.append([float(value) for value in fields[2 + count:5 + count]])
            stamps.append(float(fields[-1]))
    if not rows or len({len(row) for row in rows}) != 1:
        raise ValueError(f"{path}: no FLASER scans of one beam count")
    ranges = np.array(rows)
    beams = ranges.shape[1]
    increment = FIELD_OF_VIEW / (beams - 1 if beams % 2 else beams)
    marker = ranges.max()
    if np.mean(ranges == marker) >= MARKER_SHARE:
        ranges[ranges == marker] = math.inf
    return LaserLog(name or _stem(path), _usable_stamps(np.array(stamps)), ranges, np.array(poses),
                    -FIELD_OF_VIEW / 2, increment)


def _usable_stamps(stamps):
    """The log's own timestamps when they increase with sane gaps, else one scan per SCAN_PERIOD_FALLBACK."""
    gaps = np.diff(stamps)
    if len(gaps) and (gaps > 0).all() and gaps.max() < 300:
        return stamps - stamps[0]
    return np.arange(len(stamps)) * SCAN_PERIOD_FALLBACK


def _stem(path):
    name = str(path).rsplit("/", 1)[-1]
    for suffix in (".gz", ".log", "-corrected"):
        if name.endswith(suffix):
            name = name[:-len(suffix)]
    return name


def radish_logs(folder) -> List[str]:
    """Paths of the Radish logs in a folder, sorted by name."""
    return sorted(glob.glob(str(folder) + "/*-corrected.log.gz"))
