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
  leaves the along-corridor direction loose --, optimised as a pose graph from the reference)
  scored against the reference with the relations metric. No mapper that follows the scans can
  be expected to score much below it.
"""
import math

import numpy as np

from turtlebot3c_common.se2 import relative, transform_points, wrap_angle
from turtlebot3c_sim.evaluation import contradicts, relative_pose_errors
from turtlebot3c_slam.line_icp import LineCloud, align
from turtlebot3c_slam.pose_graph import PoseGraph

MAX_RANGE = 20.0        # m: farther echoes are too coarse in angle to fit lines to
NEIGHBOUR_SCANS = 3     # consistency: each scan against the next three
FLOOR_RADIUS = 3.0      # m: scans this close are matched for the floor...
FLOOR_TURN = 1.0        # rad: ...unless they look in directions this different (little overlap)
FLOOR_SPACING = 0.5     # m: a dense log is thinned to scans this far apart for the floor (cost)
ICP_SIGMA = 0.01        # m, a SICK's range noise: scales each match's information
REFERENCE_INFORMATION = np.diag([1.0, 1.0, 100.0])  # 1 m, 0.1 rad: weak next to any ICP match


class ScanSet:
    """A log's scans as LineClouds (points, k-d tree, line normals), each in its robot frame."""

    def __init__(self, log):
        angles = log.angle_min + np.arange(log.beams) * log.angle_increment
        directions = np.column_stack((np.cos(angles), np.sin(angles)))
        self.clouds = []
        for ranges in log.ranges:
            usable = np.isfinite(ranges) & (ranges > 0.05) & (ranges < MAX_RANGE)
            self.clouds.append(LineCloud(directions[usable] * ranges[usable, None]))

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


def match(scans, i, j, start):
    """Point-to-line ICP of scan j against scan i from `start`: (pose of j seen from i, 3x3
    information in the pose's frame), or None when they do not overlap enough."""
    aligned = align(scans.clouds[i], scans.clouds[j].points, start)
    if aligned is None:
        return None
    pose, hessian = aligned
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    to_pose_frame = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
    return pose, to_pose_frame.T @ hessian @ to_pose_frame / ICP_SIGMA ** 2


def most_consistent_trajectory(scans, reference):
    """The trajectory that agrees best with the scans, found from the reference (see the module's doc)."""
    graph = PoseGraph(huber_delta=3.0)
    for pose in reference:
        graph.add_node(pose)
    for i in range(1, len(reference)):  # holds together stretches the scans leave unmatched
        graph.add_edge(i - 1, i, relative(tuple(reference[i - 1]), tuple(reference[i])), REFERENCE_INFORMATION)
    for i in range(len(reference)):
        gaps = np.hypot(reference[:, 0] - reference[i, 0], reference[:, 1] - reference[i, 1])
        for j in np.flatnonzero(gaps < FLOOR_RADIUS):
            turn = abs(wrap_angle(reference[j, 2] - reference[i, 2]))
            if j <= i or (j - i > NEIGHBOUR_SCANS and turn > FLOOR_TURN):
                continue
            matched = match(scans, i, j, relative(tuple(reference[i]), tuple(reference[j])))
            if matched is not None:
                graph.add_edge(i, j, matched[0], matched[1], robust=True)
    graph.optimize(iterations=20)
    return graph.poses.copy()


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
    """Where the scans put j seen from i: ICP from each start, and of the poses it reaches the one
    that lays the most points of j on i's lines (None when they overlap too little). ICP from the
    reference's pose alone would judge by the reference: at csail's end, where the reference turns
    11 degrees that the scans do not, it stops in a minimum that fits half as well."""
    best, best_fit = None, -1
    for start in starts:
        matched = match(scans, i, j, start)
        if matched is None:
            continue
        fit = scans.clouds[i].points_on_lines(scans.clouds[j].points, matched[0])
        if fit > best_fit:
            best, best_fit = matched[0], fit
    return best
