"""Our SLAM on real laser logs (Radish, in benchmarks/data/radish/) with odometry that errs as a real robot's.

The one path from a log to scored figures, for benchmarks/bench_slam_real and the real-data
regression test: read the log, make odometry from its reference poses with a seeded error
model (turtlebot3c_sim.odometry_error), feed every scan to the SLAM core with the shipped
parameters (src/turtlebot3c_slam/config/slam.yaml), and score the per-scan trajectory with the
relations metric, ATE after alignment and the loop closures against the reference.
"""
import math
import resource
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml

from turtlebot3c_sim.carmen_log import read_laser_log
from turtlebot3c_sim.evaluation import aligned_trajectory_error, false_relations, relative_pose_errors
from turtlebot3c_sim.odometry_error import SEVERITIES, noisy_odometry
from turtlebot3c_slam.slam import Slam, SlamConfig
from turtlebot3c_slam.slam_scan import ScanGeometry

REPO = Path(__file__).resolve().parent.parent
RADISH = REPO / "benchmarks" / "data" / "radish"
SHIPPED_SLAM_CONFIG = REPO / "src" / "turtlebot3c_slam" / "config" / "slam.yaml"


def load_log(name, scans=None):
    log = read_laser_log(RADISH / f"{name}-corrected.log.gz", name)
    return log.head(scans) if scans else log


def shipped_slam_config():
    return SlamConfig.from_dict(yaml.safe_load(SHIPPED_SLAM_CONFIG.read_text()))


def geometry_of(log):
    return ScanGeometry(log.angle_min, log.angle_increment, log.beams, 0.0, math.inf)


class SlamRun(NamedTuple):
    trajectory: np.ndarray      # (N, 3) per scan, after loop closures
    odometry: np.ndarray        # (N, 3) the odometry the SLAM was given
    closures: list              # [(scan i, scan j, measured pose of j seen from i)]
    seconds: float              # CPU seconds in the SLAM
    scan_seconds: np.ndarray    # (N,) CPU seconds per scan
    peak_rss_mb: float


class Score(NamedTuple):
    translation: float   # m, mean relation error
    rotation: float      # deg
    ate: float           # m, after alignment
    closures: int
    false_closures: int


def run_slam(log, severity, seed, config=None):
    """Our SLAM over every scan of `log` with odometry of `severity` (a name in SEVERITIES)."""
    odometry = noisy_odometry(log.reference, SEVERITIES[severity], seed)
    slam = Slam(config or shipped_slam_config())
    geometry = geometry_of(log)
    keyframe_scan = {}
    scan_seconds = np.zeros(len(log.stamps))
    for index, (stamp, ranges, odom) in enumerate(zip(log.stamps, log.ranges, odometry)):
        before = time.process_time()
        keyframes = len(slam.keyframes)
        slam.add_scan(float(stamp), ranges, geometry, odom)
        if len(slam.keyframes) > keyframes:
            keyframe_scan[len(slam.keyframes) - 1] = index
        scan_seconds[index] = time.process_time() - before
    trajectory = np.array([pose[1:] for pose in slam.trajectory()])
    closures = [(keyframe_scan[old], keyframe_scan[new], measured) for old, new, measured, _ in slam.loop_closures]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return SlamRun(trajectory, odometry, closures, float(scan_seconds.sum()), scan_seconds, peak)


def score(log, trajectory, closures=()):
    relations = relative_pose_errors(trajectory, log.reference, log.travel())
    return Score(relations.translation, math.degrees(relations.rotation),
                 aligned_trajectory_error(trajectory, log.reference), len(closures),
                 false_relations(list(closures), log.reference))
