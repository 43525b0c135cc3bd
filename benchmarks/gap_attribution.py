"""Which of a mapper's error against the reference is the mapper's, and which the reference's.

The relations error of a trajectory (turtlebot3c_sim.evaluation) comes mostly from a few steps,
scan to scan, that it takes otherwise than the reference. For each such step:
- the gain: how much lower the relations error would be with that step as the reference takes
  it (every later pose moved with it: the metric is frame-free, so only the relations across
  the step change); it is negative where the step's error offsets another's (one scan
  misplaced: the step into it and the step out of it);
- the scans' own word: how many of the scan's points lie on the lines of the BEHIND (3) scans
  before it, laid at the trajectory's relative poses and at the reference's. Where the
  reference's step lays SIDE_MARGIN times as many, the scans side with the reference and the
  gain is the mapper's to take; where the trajectory's does, the reference errs there; in
  between the scans cannot tell (a corridor along its length, a turn on the spot that leaves
  little overlap), and only odometry decides.
"""
import math
from typing import NamedTuple

import numpy as np

from turtlebot3c_common.se2 import compose, moved_from, relative
from turtlebot3c_sim.evaluation import relation_errors, relative_pose_errors

BEHIND = 3          # scans before a step's scan that it is laid on
SIDE_MARGIN = 1.1   # times as many points on lines: the scans side with one of the two
CANDIDATES = 10     # steps furthest off in translation, and as many in rotation, are weighed


class StepGap(NamedTuple):
    scan: int                   # the step from scan - 1 to scan
    translation: float          # m, the step's difference from the reference's
    rotation: float             # degrees
    gain: float                 # m of relations error the reference's step would take off (see the doc)
    fit_trajectory: int         # points on the BEHIND scans' lines at the trajectory's step
    fit_reference: int          # ...and at the reference's
    sides_with: str             # "trajectory", "reference" or "neither"


def step_differences(trajectory, reference):
    """(N - 1,) m and (N - 1,) rad: how far each step, scan to scan, lies from the reference's."""
    first = np.arange(len(reference) - 1)
    return relation_errors(np.asarray(trajectory, dtype=np.float64)[:, :3],
                           np.asarray(reference, dtype=np.float64)[:, :3], first, first + 1)


def with_reference_steps(trajectory, reference, scans):
    """The trajectory with the steps into `scans` taken as the reference takes them."""
    mended = np.array(trajectory, dtype=np.float64)[:, :3]
    for i in sorted(scans):
        step = relative(tuple(reference[i - 1]), tuple(reference[i]))
        mended = moved_from(mended, i, compose(tuple(mended[i - 1]), step))
    return mended


def fit_behind(scans, trajectory, i):
    """How many of scan i's points lie on the lines of the BEHIND scans before it, at the trajectory's poses."""
    return sum(scans.clouds[k].points_on_lines(scans.clouds[i].points,
                                               relative(tuple(trajectory[k]), tuple(trajectory[i])))
               for k in range(max(0, i - BEHIND), i))


def sides_with(fit_trajectory, fit_reference):
    if fit_trajectory > SIDE_MARGIN * fit_reference:
        return "trajectory"
    if fit_reference > SIDE_MARGIN * fit_trajectory:
        return "reference"
    return "neither"


def largest_gaps(scans, trajectory, reference, travel):
    """StepGaps of the steps furthest from the reference's, the largest gain first."""
    translation, rotation = step_differences(trajectory, reference)
    candidates = set(np.argsort(-translation)[:CANDIDATES]) | set(np.argsort(-rotation)[:CANDIDATES])
    whole = relative_pose_errors(trajectory, reference, travel).translation
    gaps = []
    for step in sorted(candidates):
        i = int(step) + 1
        mended = with_reference_steps(trajectory, reference, [i])
        fits = fit_behind(scans, trajectory, i), fit_behind(scans, reference, i)
        gaps.append(StepGap(i, float(translation[step]), math.degrees(rotation[step]),
                            whole - relative_pose_errors(mended, reference, travel).translation,
                            *fits, sides_with(*fits)))
    return sorted(gaps, key=lambda gap: -gap.gain)
