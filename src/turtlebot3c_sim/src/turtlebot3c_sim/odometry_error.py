"""Wheel odometry as a real robot's would be, made from a reference trajectory. Pure numpy; no rospy.

Real datasets come with the poses a good offline SLAM found, not with the robot's raw
odometry; a benchmark of SLAM on them needs odometry that errs as a differential drive's
does. Each step between two reference poses is split into a turn, a straight move and a
turn (as wheel encoders see a short arc), and corrupted with, per severity:
- *scale*: the distance travelled reads `distance_scale` too long or too short, and turns
  `turn_scale` (rad per rad turned): worn or mis-measured wheels and an uncertain track
  width; the sign of each is drawn once per run;
- *drift*: a heading error of `drift_per_metre` rad per metre, with a drawn sign, from
  unequal wheel radii;
- *random walk*: zero-mean noise growing with the square root of the distance and angle
  travelled (`walk_xy` m and `walk_theta` rad per sqrt metre / sqrt radian);
- *slips*: with probability `slip_per_metre` per metre, a wheel slips: the distance of that
  step reads up to `slip_loss` long or short, as likely either way (a wheel spinning on a
  smooth floor or against an obstacle reads long; a robot pushed, or skidding on after
  braking, reads short), and the heading jumps by up to `slip_turn` rad.
Seeded: the same severity and seed give the same odometry.
"""
import math
from typing import NamedTuple

import numpy as np

from turtlebot3c_common.se2 import compose, moved_from, relative, wrap_angle


class OdometryError(NamedTuple):
    distance_scale: float   # fraction of the distance
    turn_scale: float       # rad per rad turned
    drift_per_metre: float  # rad per m
    walk_xy: float          # m per sqrt(m)
    walk_theta: float       # rad per sqrt(m + rad)
    slip_per_metre: float   # probability per m
    slip_loss: float        # fraction of a step's distance, either way, at most
    slip_turn: float        # rad, at most


SEVERITIES = {
    "mild": OdometryError(0.02, 0.05, 0.005, 0.01, 0.005, 0.005, 0.3, 0.05),
    "moderate": OdometryError(0.05, 0.15, 0.01, 0.02, 0.01, 0.01, 0.5, 0.1),
    # At least as bad as issue #21 asks tracking to survive: 10 % in distance, 0.3 rad per
    # radian turned.
    "severe": OdometryError(0.10, 0.30, 0.02, 0.03, 0.02, 0.02, 0.7, 0.2),
}


def noisy_odometry(reference, error, seed):
    """Odometry poses (N, 3), starting at the first reference pose, that err as `error` says."""
    reference = np.asarray(reference, dtype=np.float64)
    random = np.random.RandomState(seed)
    distance_sign, turn_sign, drift_sign = random.choice((-1.0, 1.0), size=3)
    odometry = [tuple(reference[0])]
    for before, after in zip(reference[:-1], reference[1:]):
        step = relative(tuple(before), tuple(after))
        length = math.hypot(step[0], step[1])
        heading = math.atan2(step[1], step[0]) if length > 1e-6 else 0.0
        if abs(heading) > math.pi / 2:
            heading = wrap_angle(heading - math.pi)   # a step backwards is driven backwards, not turned to
            length = -length
        first_turn, second_turn = heading, wrap_angle(step[2] - heading)
        turned = abs(first_turn) + abs(second_turn)
        length *= 1.0 + distance_sign * error.distance_scale
        first_turn *= 1.0 + turn_sign * error.turn_scale
        second_turn *= 1.0 + turn_sign * error.turn_scale
        second_turn += drift_sign * error.drift_per_metre * abs(length)
        length += random.normal(0.0, error.walk_xy * math.sqrt(abs(length)))
        second_turn += random.normal(0.0, error.walk_theta * math.sqrt(abs(length) + turned))
        if random.uniform() < error.slip_per_metre * abs(length):
            length *= 1.0 - random.uniform(-error.slip_loss, error.slip_loss)
            second_turn += random.uniform(-error.slip_turn, error.slip_turn)
        moved = (length * math.cos(first_turn), length * math.sin(first_turn), first_turn + second_turn)
        odometry.append(compose(odometry[-1], moved))
    return np.array(odometry)


def with_slip(odometry, scan, length):
    """`odometry` with the step into `scan` read as `length` m (its direction and turn kept),
    every later pose moved with it: one slip, put where a test needs it whatever the seed drew."""
    before, after = tuple(odometry[scan - 1]), tuple(odometry[scan])
    step = relative(before, after)
    stretch = length / math.hypot(step[0], step[1])
    return moved_from(odometry, scan, compose(before, (step[0] * stretch, step[1] * stretch, step[2])))
