"""The poses that agree best with the scans themselves, found from a first estimate. Pure numpy and
scipy; no rospy.

Point-to-line ICP between every pair of scans near each other (line_icp), each match weighted by
how well it pins the pose (a corridor leaves the along-corridor direction loose), added to a pose
graph of the first estimate and optimised with it: the graph's own edges (the SLAM's tracking and
loop closures, or a chain of relative poses) hold together what the scans leave unmatched.

Tracking lays each scan on a grid map of match_resolution cells, and a loop closure lays it on a
submap: both leave centimetres and tenths of a degree between neighbouring keyframes, and those
add up along the path. Once the loops are closed the first estimate is within ICP's reach, and
this takes much of that error out. It costs a twentieth to a sixth of the SLAM's own time, so it
runs once, at the end of a session (remap_bag, and mapping's stop through the node's refine_map).
"""
import copy
import math

import numpy as np

from turtlebot3c_common.se2 import poses_within, relative, wrap_angle

from . import line_icp
from .pose_graph import PoseGraph

MAX_RANGE = 20.0        # m: farther echoes are too coarse in angle to fit lines to
RADIUS = 3.0            # m: scans this close are matched...
TURN = 1.0              # rad: ...unless they look in directions this different (little overlap)
NEIGHBOURS = 3          # ...but each scan is always matched with the next three
PARTNERS = 4            # and with at most this many others (see _partners)
RANGE_SIGMA = 0.01      # m, the scanner's range noise: scales each match's information
# 1 m, 0.1 rad: the first estimate's relative poses, weak next to any ICP match.
FIRST_ESTIMATE_INFORMATION = np.diag([1.0, 1.0, 100.0])
# A match that moves the pair further than this from the first estimate is left out: there the
# estimate is off by more than a refinement mends (a loop left open), and ICP from that far
# may slide to a look-alike.
MAX_SHIFT = 0.3         # m
MAX_TURN = 0.1          # rad
ICP_ITERATIONS = 10     # from an estimate this close ICP settles in a few
# m and rad: a match whose step is this small has settled, far below the scans' 1 cm noise.
# On freiburg-079 it takes half the ICP iterations of line_icp.SETTLED, for the same error.
# Stopping early leaves a pose a little nearer its start, so a measurement of how far the
# scans pull poses from where they start (benchmarks/scan_consistency) settles to the end.
SETTLED = 1e-3
# m and rad: after a step this small a match keeps its pairs (line_icp.align). On freiburg-079
# the refinement then takes a quarter to a third less time, and over bench_slam_real's 33 rows
# its relations error is 0.0004 m lower on average (docs/benchmarks.md, session 41).
KEEP_PAIRS = 5e-3
HUBER_DELTA = 3.0
ITERATIONS = 20


def scan_cloud(hits):
    """A scan's hits (N x 2, its own frame) as the LineCloud the matches use."""
    hits = np.asarray(hits, dtype=np.float64).reshape(-1, 2)
    return line_icp.LineCloud(hits[np.hypot(hits[:, 0], hits[:, 1]) < MAX_RANGE])


def match(target, source_points, start, iterations=line_icp.ITERATIONS, settled=line_icp.SETTLED, keep_pairs=0.0):
    """Point-to-line ICP of `source_points` against the LineCloud `target` from `start`, each point
    paired only within the lines (line_icp's within_lines): (pose of the source seen from the
    target, 3x3 information in that pose's frame), or None when they do not overlap enough."""
    aligned = line_icp.align(target, source_points, start, iterations, settled, keep_pairs, within_lines=True)
    if aligned is None:
        return None
    pose, hessian = aligned
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    to_pose_frame = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
    return pose, to_pose_frame.T @ hessian @ to_pose_frame / RANGE_SIGMA ** 2


def refine(graph, clouds, settled=SETTLED, keep_pairs=KEEP_PAIRS):
    """The poses (N x 3) of `graph` (a PoseGraph of N nodes, kept as it is) that agree best with the
    scans `clouds` (N LineClouds, each in its node's frame): the graph's own edges, plus an ICP
    match between every pair of nodes near each other, optimised from the graph's poses. Each
    match stops at a step below `settled` and keeps its pairs after one below `keep_pairs` (m
    and rad)."""
    refined = copy.deepcopy(graph)
    poses = graph.poses
    for i in range(len(poses)):
        for j in _partners(poses, i):
            start = relative(tuple(poses[i]), tuple(poses[j]))
            matched = match(clouds[i], clouds[j].points, start, ICP_ITERATIONS, settled, keep_pairs)
            if matched is not None and within_reach(start, matched[0]):
                refined.add_edge(i, j, matched[0], matched[1], robust=True)
    refined.optimize(iterations=ITERATIONS)
    return refined.poses.copy()


def _partners(poses, i):
    """The later nodes node i is matched with: the next NEIGHBOURS, and of the others within RADIUS
    that look within TURN the same way, the PARTNERS nearest (where the robot passed many times,
    each pass's nearest keyframes tie the passes together as well as all of them do)."""
    later = np.arange(i + 1, len(poses))
    gaps = np.hypot(poses[later, 0] - poses[i, 0], poses[later, 1] - poses[i, 1])
    turns = np.abs(wrap_angle(poses[later, 2] - poses[i, 2]))
    neighbours = later[:NEIGHBOURS][gaps[:NEIGHBOURS] < RADIUS]
    others = np.flatnonzero((later > i + NEIGHBOURS) & (gaps < RADIUS) & (turns <= TURN))
    nearest = others[np.argsort(gaps[others], kind="stable")[:PARTNERS]]
    return np.concatenate((neighbours, np.sort(later[nearest])))


def chain(poses, information=FIRST_ESTIMATE_INFORMATION):
    """A PoseGraph of `poses` (N x 3), each joined to the next by their relative pose."""
    graph = PoseGraph(huber_delta=HUBER_DELTA)
    for pose in poses:
        graph.add_node(pose)
    for i in range(1, len(poses)):
        graph.add_edge(i - 1, i, relative(tuple(poses[i - 1]), tuple(poses[i])), information)
    return graph


def within_reach(start, matched):
    """Whether a match lies within MAX_SHIFT and MAX_TURN of where it started: the refinement
    takes no match farther away."""
    return poses_within(start, matched, MAX_SHIFT, MAX_TURN)
