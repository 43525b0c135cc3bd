"""How far the robot goes per metre its odometry reads, learnt from the scan matches. Pure
numpy and scipy; no rospy.

A wheel whose radius is a few per cent off makes every distance odometry reads that much long
or short, step after step. Tracking searches around odometry's prediction, and where the scans
cannot tell how far the robot went (along a featureless corridor) the prediction stands:
uncorrected, odometry that reads 10 % short draws such a corridor 10 % short, and the matches
after it follow the map's scale (infinite-corridor, severe odometry reading short: 0.127-0.136 m
of relation error; corrected, 0.083-0.088 m).

OdometryScale fits, by weighted least squares over the recent path,

    distance travelled = scale * odometry's distance

to the steps between scans that both matched well, and corrects each new step by it. Each step
counts by how firmly its scan's shape pins the motion along the robot's heading (0 along a
corridor, 1 in a room): a match that could only keep the prediction teaches nothing, where
counted like any other it would confirm whatever scale was learnt. Old evidence fades as new
comes in (half of it after `memory` metres of firmly matched path), so the scale follows a
change of floor; a prior of no error keeps it at 1 until the robot has moved, and limits
bound it.

Only the distance is corrected: learning the turn scale and heading drift as well did less for
the real logs and, on one, turned the map the wrong way (docs/benchmarks.md).
"""
import math

import numpy as np

from .line_icp import line_normals

SCALE_LIMITS = (0.8, 1.25)
# How precisely a good match measures a step, about a tracking cell: the unit in which the
# fit's evidence is weighed against the prior, "odometry is right, give or take the error the
# SLAM's config allows". With 4 cm steps (a TurtleBot3 at 5 Hz) the prior holds for the first
# 2 m or so, so the tracking's own short-lived errors do not set the scale.
STEP_PRECISION = 0.03  # m


class OdometryScale:
    def __init__(self, memory=20.0, distance_error=0.1):
        """`memory`: m of firmly matched path after which a step's evidence counts half;
        `distance_error`: how far odometry's distances may be off (1 sigma, m per m), as
        SlamConfig's odometry_error_distance."""
        self.memory = memory
        self._prior = (STEP_PRECISION / distance_error) ** 2
        self.scale = 1.0
        self._odometry_squares = 0.0   # weighted sum of odometry's distance^2, faded as evidence comes in
        self._products = 0.0           # weighted sum of odometry's distance * the matched distance

    def corrected(self, step):
        """Odometry's step (x, y, theta from the pose at its start) as the robot most likely moved."""
        return (step[0] * self.scale, step[1] * self.scale, step[2])

    def learn(self, step, matched, weight=1.0):
        """Odometry's step, the same step as the scans matched it (both from the pose at its
        start), and how firmly the match pinned it along the motion, in [0, 1]."""
        length = _signed_length(step)
        fade = 0.5 ** (weight * abs(length) / self.memory)
        self._odometry_squares = fade * self._odometry_squares + weight * length * length
        self._products = fade * self._products + weight * length * _signed_length(matched)
        scale = (self._products + self._prior) / (self._odometry_squares + self._prior)
        self.scale = min(max(scale, SCALE_LIMITS[0]), SCALE_LIMITS[1])


def firmness_along_heading(points):
    """How firmly a scan's points (N, 2, robot frame) pin the robot along its heading, from the
    lines through them: 1 where as many walls face it as run along it (a room), 0 where all run
    along it (a corridor, where a match can only keep its prediction)."""
    if len(points) < 2:
        return 0.0
    # A line's normal points along the heading as much as the line runs across it.
    return min(1.0, 2.0 * float(np.mean(line_normals(points)[:, 0] ** 2)))


def _signed_length(step):
    """The step's length, negative when it went backwards."""
    return math.copysign(math.hypot(step[0], step[1]), step[0])
