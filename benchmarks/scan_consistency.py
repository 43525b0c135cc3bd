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
  scored against the reference with the relations metric. No mapper that follows the scans can
  be expected to score much below it.
"""
import math

import numpy as np

from turtlebot3c_common.se2 import relative, transform_points
from turtlebot3c_sim.evaluation import contradicts, relative_pose_errors
from turtlebot3c_slam import line_icp, scan_refinement

NEIGHBOUR_SCANS = 3     # consistency: each scan against the next three
FLOOR_SPACING = 0.5     # m: a dense log is thinned to scans this far apart for the floor (cost)


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
        return self.clouds[i].pairs(transform_points(pose, self.clouds[j].points))


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
    return scan_refinement.refine(scan_refinement.chain(reference), scans.clouds, line_icp.SETTLED)


def floor(log):
    """Relations error (m, deg) of the most scan-consistent trajectory against the reference, on
    the log's scans FLOOR_SPACING apart."""
    thinned = _thinned(log)
    best = most_consistent_trajectory(ScanSet(thinned), thinned.reference)
    error = relative_pose_errors(best, thinned.reference, thinned.travel())
    return error.translation, math.degrees(error.rotation)


def _thinned(log):
    travel, keep, last = log.travel(), [], -math.inf
    for index, distance in enumerate(travel):
        if distance - last >= FLOOR_SPACING:
            keep.append(index)
            last = distance
    return log._replace(stamps=log.stamps[keep], ranges=log.ranges[keep], reference=log.reference[keep])


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
    cost is not this count): the starts themselves are candidates."""
    best, best_fit = None, -1
    for start in starts:
        matched = scan_refinement.match(scans.clouds[i], scans.clouds[j].points, start)
        if matched is None:
            continue
        for pose in (matched[0], tuple(start)):
            fit = scans.clouds[i].points_on_lines(scans.clouds[j].points, pose)
            if fit > best_fit:
                best, best_fit = pose, fit
    return best
