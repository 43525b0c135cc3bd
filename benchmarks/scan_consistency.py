"""How well a trajectory agrees with a log's own scans, and how far the reference lets any mapper get.

The Radish logs' reference trajectories come from an offline SLAM, not from a ground truth: they
carry their own local error. Two figures for benchmarks/bench_slam_real, neither of which trusts
the reference:
- consistency(trajectory): lay every scan over the next few at the trajectory's relative poses
  and take the median point-to-line distance between them (m). A trajectory that agrees with
  what the laser saw scores low; it needs no reference at all.
- false_by_scans(closures): a loop closure judged by the two scans it joins rather than by the
  reference alone: ICP of one against the other, from the reference's relative pose and from the
  claimed one, says where the scans put them (the pose that lays more points on lines); a claim
  farther from that than the tolerances is false (where the two scans overlap too little for
  ICP, the reference decides).
- floor(): the trajectory that agrees best with the scans (point-to-line ICP between every pair
  of scans near each other, each match weighted by how well it pins the pose -- a corridor
  leaves the along-corridor direction loose --, optimised as a pose graph from the reference:
  turtlebot3c_slam.scan_refinement, the SLAM's own refinement at the end)
  scored against the reference with the relations metric, on every scan, as the mappers are.
  No mapper that follows the scans can be expected to score much below it. The refinement mends
  what lies within its reach of where it starts; where the reference errs beyond that (csail's
  turns 11-21 degrees at scans its neighbours put elsewhere), the scan, with the run of scans it
  starts, is first moved where the scan before puts it (reseated()).
"""
import math

import numpy as np

from turtlebot3c_common.se2 import compose, inverse, relative, transform_points
from turtlebot3c_sim.evaluation import contradicts, relative_pose_errors
from turtlebot3c_slam import line_icp, scan_refinement

NEIGHBOUR_SCANS = 3     # consistency: each scan against the next three
# reseated(): ICP of one scan against the one before also starts this far either way from the
# reference's heading (the reference's own errors seen so far reach 21 degrees)...
RESEAT_TURNS = np.radians([8.0, 16.0, 24.0])
# ...and the scans' step replaces the reference's where it lays this many times as many points
# on lines, and this many more: a step the scans clearly prefer, not one ICP slid to.
RESEAT_FIT_RATIO, RESEAT_FIT_MARGIN = 1.5, 30


class ScanSet:
    """A log's scans as LineClouds (points, k-d tree, line normals), each in its robot frame."""

    def __init__(self, log):
        angles = log.angle_min + np.arange(log.beams) * log.angle_increment
        directions = np.column_stack((np.cos(angles), np.sin(angles)))
        self.clouds = []
        for ranges in log.ranges:
            usable = np.isfinite(ranges) & (ranges > 0.05)
            self.clouds.append(scan_refinement.scan_cloud(directions[usable] * ranges[usable, None]))

    def __len__(self):
        return len(self.clouds)

    def pairs(self, i, j, pose):
        """Scan j laid into scan i's frame at `pose` (j seen from i): LineCloud.pairs."""
        return self.clouds[i].pairs(transform_points(pose, self.clouds[j].points), pose)


def consistency(scans, trajectory):
    """Mean over scan pairs (each scan and the next NEIGHBOUR_SCANS) of the median point-to-line
    distance (m) between them laid at the trajectory's relative poses."""
    medians = []
    for i in range(len(scans)):
        for j in range(i + 1, min(i + 1 + NEIGHBOUR_SCANS, len(scans))):
            paired = scans.pairs(i, j, relative(tuple(trajectory[i]), tuple(trajectory[j])))
            if paired is not None:
                medians.append(np.median(np.abs(paired[2])))
    return float(np.mean(medians)) if medians else math.nan


def most_consistent_trajectory(scans, reference):
    """The trajectory that agrees best with the scans, found from the reference (see the module's doc)."""
    start = reseated(scans, reference)
    # Each ICP match settled to line_icp's finest step, its pairs looked up afresh at every
    # iteration: a measure that the refinement's shortcuts for speed do not move.
    return scan_refinement.refine(scan_refinement.chain(start), scans.clouds, line_icp.SETTLED, keep_pairs=0.0)


def reseated(scans, reference):
    """The reference with each run of scans it misplaces beyond the refinement's reach moved, as
    one, to where the scans put the first of them (see _scans_step). A run ends at the first scan
    that lies on the scan before the run's lines better where the reference puts it than where
    the run went (csail's scans 397-399 together, freiburg-079's 4088-4089)."""
    poses = np.array(reference, dtype=np.float64)[:, :3]
    i = 1
    while i < len(poses):
        step = relative(tuple(poses[i - 1]), tuple(poses[i]))
        scans_step = _scans_step(scans, i, step)
        if scans_step is None:
            i += 1
            continue
        moved = compose(tuple(poses[i - 1]), scans_step)
        correction = compose(moved, inverse(tuple(poses[i])))
        end = i + 1
        while end < len(poses) and not _back_on_reference(scans, i - 1, poses, end, correction):
            end += 1
        for run in range(i, end):
            poses[run] = compose(correction, tuple(poses[run]))
        i = end
    return poses


def _scans_step(scans, i, step):
    """Scan i seen from scan i - 1 where the scans put it best, if that is beyond the refinement's
    reach from the reference's `step` and fits far better; else None."""
    target, points = scans.clouds[i - 1], scans.clouds[i].points
    to_beat = RESEAT_FIT_RATIO * target.points_on_lines(points, step) + RESEAT_FIT_MARGIN
    if to_beat >= len(points):
        return None  # nothing can fit that much better
    turns = np.concatenate(([0.0], RESEAT_TURNS, -RESEAT_TURNS))
    best = best_alignment(scans, i - 1, i, [(step[0], step[1], step[2] + turn) for turn in turns])
    if best is None or scan_refinement.within_reach(step, best):
        return None
    return best if target.points_on_lines(points, best) > to_beat else None


def _back_on_reference(scans, before, poses, k, correction):
    """Whether scan k lies on scan `before`'s lines at least as well where `poses` put it as moved by `correction`."""
    target, points = scans.clouds[before], scans.clouds[k].points
    where_it_is = relative(tuple(poses[before]), tuple(poses[k]))
    moved = relative(tuple(poses[before]), compose(correction, tuple(poses[k])))
    return target.points_on_lines(points, where_it_is) >= target.points_on_lines(points, moved)


def floor(log):
    """Relations error (m, deg) of the most scan-consistent trajectory against the reference."""
    best = most_consistent_trajectory(ScanSet(log), log.reference)
    error = relative_pose_errors(best, log.reference, log.travel())
    return error.translation, math.degrees(error.rotation)


def false_by_scans(scans, closures, reference):
    """How many closures [(scan i, scan j, claimed pose of j seen from i)] the two scans contradict."""
    false = 0
    for i, j, claimed in closures:
        expected = relative(tuple(reference[i]), tuple(reference[j]))
        aligned = best_alignment(scans, i, j, (expected, tuple(claimed)))
        false += contradicts(tuple(claimed), aligned if aligned is not None else expected)
    return false


def best_alignment(scans, i, j, starts):
    """Where the scans put j seen from i: of the starts and the poses ICP reaches from them, the one
    that lays the most points of j on i's lines (None when they overlap too little for ICP). ICP
    from the reference's pose alone would judge by the reference: at csail's end, where the
    reference turns 11 degrees that the scans do not, it stops in a minimum that fits half as well.
    And ICP can slide along a corridor to a pose that fits worse than where it started (ICP's own
    cost is not this count): the starts themselves are candidates. ICP here pairs points past a
    line's end, as the SLAM's own checks of a closure do (line_icp.LineCloud.pairs): it starts
    tenths of a metre and degrees off."""
    best, best_fit = None, -1
    for start in starts:
        matched = line_icp.align(scans.clouds[i], scans.clouds[j].points, start)
        if matched is None:
            continue
        for pose in (matched[0], tuple(start)):
            fit = scans.clouds[i].points_on_lines(scans.clouds[j].points, pose)
            if fit > best_fit:
                best, best_fit = pose, fit
    return best
