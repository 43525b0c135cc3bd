"""How the robot's odometry errs, learnt from the scan matches, to correct each prediction. Pure
numpy; no rospy.

A wheel whose radius is a few per cent off makes every distance odometry reads that much long or
short; a track width a few per cent off, or wheels that skid as the robot turns on carpet, makes
every turn read short or long; wheels of unequal radii make the heading drift as it drives
straight. Each error repeats step after step, so the matches can measure it:
- *Distance*: tracking searches around odometry's prediction, and where the scans cannot tell how
  far the robot went (along a featureless corridor) the prediction stands. Uncorrected, odometry
  that reads 10 % short draws such a corridor 10 % short, and the matches after it follow the
  map's scale (infinite-corridor, severe odometry reading short: 0.127-0.136 m of relation error;
  corrected, 0.083-0.088 m).
- *Turns*: turning on the spot, a 180-degree scan sees new ground at each step and its match can
  be too weak to overrule a prediction that turns 30 % short (fhw, severe, seed 3: the matches
  followed odometry for five scans and the rest of the map turned 45 degrees).

OdometryCalibration fits, by weighted least squares over the recent path,

    distance travelled = distance_scale * odometry's distance
    angle turned       = turn_scale * odometry's turn + heading_drift * odometry's distance

to the steps between scans that both matched well, and corrects each new step by them. A distance
step counts by how firmly its scan's shape pins the motion along the robot's heading (0 along a
corridor, 1 in a room): a match that could only keep the prediction teaches nothing, where counted
like any other it would confirm whatever scale was learnt. Any match pins a turn. Old evidence
fades as new comes in (half of it after `memory` metres of path, or TURN_MEMORY radians turned),
so the fit follows a change of floor; a prior of no error holds until the robot has moved, and
limits bound each figure.
"""
import math

import numpy as np

from .line_icp import line_normals

SCALE_LIMITS = (0.8, 1.25)
TURN_SCALE_LIMITS = (0.65, 1.5)
HEADING_DRIFT_LIMIT = 0.1  # rad per m
# How precisely a good match measures a step: the unit in which the fit's evidence is weighed
# against the prior, "odometry is right, give or take the error the SLAM's config allows". With
# 4 cm steps (a TurtleBot3 at 5 Hz) the distance's prior holds for the first 2 m or so, so the
# tracking's own short-lived errors do not set the scale.
STEP_PRECISION = 0.03  # m, about a tracking cell
TURN_PRECISION = 0.01  # rad
TURN_MEMORY = 4 * math.pi  # rad turned after which a turn's evidence counts half


class FadingFit:
    """Weighted least squares for `target = coefficients . features`, with a Gaussian prior on the
    coefficients and old evidence fading as new comes in."""

    def __init__(self, prior, prior_weights, limits):
        self._prior = np.asarray(prior, dtype=np.float64)
        self._prior_information = np.diag(prior_weights)
        self._limits = np.asarray(limits, dtype=np.float64).T   # (lows, highs)
        self._information = np.zeros_like(self._prior_information)
        self._evidence = np.zeros_like(self._prior)
        self.coefficients = self._prior.copy()

    def add(self, features, target, weight, fade):
        """One observation of `weight`, the evidence so far first kept at `fade` (in [0, 1])."""
        features = np.asarray(features, dtype=np.float64)
        self._information = fade * self._information + weight * np.outer(features, features)
        self._evidence = fade * self._evidence + weight * target * features
        fit = np.linalg.solve(self._information + self._prior_information,
                              self._evidence + self._prior_information @ self._prior)
        self.coefficients = np.clip(fit, *self._limits)


class OdometryCalibration:
    def __init__(self, memory=20.0, distance_error=0.1, turn_error=0.12, heading_error=0.03):
        """`memory`: m of path after which a step's evidence counts half; the errors odometry may
        have (1 sigma), as SlamConfig's odometry_error_*: distance (m per m), turn (rad per rad)
        and heading (rad per m)."""
        self.memory = memory
        self._distance = FadingFit([1.0], [(STEP_PRECISION / distance_error) ** 2], [SCALE_LIMITS])
        self._turn = FadingFit([1.0, 0.0], [(TURN_PRECISION / turn_error) ** 2, (TURN_PRECISION / heading_error) ** 2],
                               [TURN_SCALE_LIMITS, (-HEADING_DRIFT_LIMIT, HEADING_DRIFT_LIMIT)])

    @property
    def distance_scale(self):
        return float(self._distance.coefficients[0])

    @property
    def turn_scale(self):
        return float(self._turn.coefficients[0])

    @property
    def heading_drift(self):
        return float(self._turn.coefficients[1])

    def corrected(self, step):
        """Odometry's step (x, y, theta from the pose at its start) as the robot most likely moved."""
        scale = self.distance_scale
        return (step[0] * scale, step[1] * scale,
                self.turn_scale * step[2] + self.heading_drift * _signed_length(step))

    def learn_distance(self, step, matched, firmness):
        """Odometry's step, the same step as the scans matched it (both from the pose at its
        start), and how firmly the match pinned it along the motion, in [0, 1]."""
        length = _signed_length(step)
        self._distance.add([length], _signed_length(matched), firmness,
                           0.5 ** (firmness * abs(length) / self.memory))

    def learn_turn(self, step, matched):
        """Odometry's step and the same step as the scans matched it. The drift is per metre
        driven forwards: backwards, the larger wheel turns the robot the other way."""
        length = _signed_length(step)
        self._turn.add([step[2], length], matched[2], 1.0,
                       0.5 ** (abs(step[2]) / TURN_MEMORY + abs(length) / self.memory))


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
