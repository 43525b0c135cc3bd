"""Loop closure for the SLAM's pose graph (slam.Slam): finding an old part of the map again,
checking the match, and closing the loop only on closures that agree. Pure numpy; no rospy.

A new keyframe near an old part of the trajectory (more than `loop_min_travel` metres of path
ago, within `loop_search_radius`) is matched, with the last few keyframes' points, against a
submap built from the old keyframes around there, over a wide window (branch and bound keeps
that fast). The map drifts along the path: the window, and how far off an old keyframe may be,
grow by `loop_drift` per metre of path between it and the newest one (a closed loop is a
shortcut; up to `loop_window_max_xy`), so that a loop a few hundred metres long still closes.

The closure's edge joins the newest keyframe to the old one nearest: a good match must also put
those two where their own scans, aligned directly (point-to-line ICP, line_icp), agree within
`loop_check_*`, for an old keyframe that sits a little wrong among its neighbours would make the
edge wrong by as much though the match was right; two keyframes that overlap too little to judge
close no loop, nor do two whose scans, aligned from further along a corridor (a metre, or as far
as the search reached), fit almost as well there. A good match is even then only a candidate:
corridors that look alike fool one match, so a closure is taken when a second one, within
`loop_pending_keyframes`, moves the map the same way; both become robust edges and the graph is
optimised, and an accepted closure the optimised graph still contradicts by more than
`loop_residual_*` is taken out again. Closures that move the map by less than half a cell only
add their edges: optimising, and redrawing the map, waits for a later closure or for
`optimize_deferred` (before a map is published or saved).

The keyframes it reads need `travel` (m of path from the first scan), `points` (the down-sampled
hits they match with) and `rays.hits` (every hit), all in the robot frame.
"""
import math

import numpy as np

from turtlebot3c_common.se2 import compose, inverse, poses_within, relative, transform_points, wrap_angle

from .line_icp import LineCloud, align
from .occupancy_grid import hit_cells
from .pose_graph import diagonal_information
from .scan_matcher import FIELD_RADIUS, GridMatcher, searched_cells, sparse_likelihood_field
from .slam_scan import voxel_filter

LEVELS = 5  # coarser maxima grids of the loop search's branch and bound, over its wide window
VIEW_TURN_WEIGHT = 1.0  # m per rad: see nearest_view
# After a long drift the widened loop search reaches other passes of the same place: its
# submap is the old keyframes nearest the newest one, up to a scan's spread beyond the window.
WIDE_SUBMAP_MARGIN = 2.0  # m
WIDE_SUBMAP_KEYFRAMES = 60
# See fits_as_well_elsewhere: probes start every ALIAS_SHIFT_STEP m up to the loop search's
# half-width (ALIAS_MIN_REACH at least) either way; a pose that lays ALIAS_FIT_SHARE of the
# points on lines as well as the closure's is a look-alike.
ALIAS_SHIFT_STEP = 0.5
ALIAS_MIN_REACH = 1.0
ALIAS_FIT_SHARE = 0.9
ALIAS_ICP_ITERATIONS = 10  # enough to settle from a metre off; 3 % of freiburg-079's time


class LoopClosure:
    """A match of the newest keyframe against an old part of the map."""

    def __init__(self, old, newest, measured, score, correction, at):
        self.old, self.newest = old, newest
        self.at = at                  # the newest keyframe's pose when matched
        self.measured = measured      # the newest keyframe seen from the old one
        self.score = score
        self.correction = correction  # the rigid motion the match applies to the newest keyframe's map

    def agrees_with(self, other, config):
        """Whether both closures move the map alike (compared where the other was matched)."""
        here = other.at
        return poses_within(compose(self.correction, here), compose(other.correction, here),
                            config.loop_agreement_xy, config.loop_agreement_theta)

    def moves_map(self, config):
        return math.hypot(self.correction[0], self.correction[1]) > config.resolution * 0.5 or \
            abs(self.correction[2]) > 0.005

    def is_edge(self, edge):
        return edge.i == self.old and edge.j == self.newest and edge.measurement == tuple(self.measured)

    def edge_in(self, graph):
        return any(self.is_edge(edge) for edge in graph.edges if edge.robust)


class DriftPath:
    """For each keyframe, the metres of path to the newest one along which the map may have drifted."""

    def __init__(self):
        self.metres = np.zeros(0)

    def extend(self, step):
        """A new keyframe `step` m of path after the last is the path's end: every keyframe is as much further."""
        self.metres = np.append(self.metres + step, 0.0)

    def shorten(self, travel, closure):
        """A closed loop joins its two keyframes (`travel`: each keyframe's m of path from the
        first scan): a keyframe's path to the newest may now run to the closure's old keyframe,
        across, and on. Only the shortcut through the one closure is taken, not chains of
        several: the path may come out longer than the shortest, and the search wider than it
        needs, never narrower. Counted from the last closure alone, the drift missed a map bent
        10-20 m elsewhere (infinite-corridor, acapulco)."""
        across = np.abs(travel - travel[closure.old]) + travel[-1] - travel[closure.newest]
        self.metres = np.minimum(self.metres, across)

    def windows(self, config, count):
        """The loop search's half-width (m) towards the first `count` keyframes: as far as the map
        may have drifted between each and the newest keyframe."""
        return np.clip(config.loop_drift * self.metres[:count], config.loop_window_xy, config.loop_window_max_xy)


def nearest_view(poses, members, pose):
    """Of the keyframes `members` (indices into `poses`), the one whose view is nearest `pose`'s:
    close by, and looking the same way (a turn of a radian counts as VIEW_TURN_WEIGHT metres), so
    that its scan overlaps the newest keyframe's as much as the old keyframes allow."""
    chosen = poses[members]
    gaps = np.hypot(chosen[:, 0] - pose[0], chosen[:, 1] - pose[1]) + \
        VIEW_TURN_WEIGHT * np.abs(wrap_angle(chosen[:, 2] - pose[2]))
    return members[int(np.argmin(gaps))]


def within_check(pose, measured, config):
    return poses_within(pose, measured, config.loop_check_xy, config.loop_check_theta)


def keyframes_agree(old, newest, measured, config, window=0.0, fit_share=ALIAS_FIT_SHARE):
    """Whether two keyframes' scans, aligned from `measured` (the newest seen from the old), stay
    within loop_check_* of it, and fit nowhere else almost as well (fits_as_well_elsewhere; the
    probes reach `window` m). On freiburg-101 the old keyframe sat 0.55 m off among its
    neighbours, and a right match made an edge to it wrong by as much. The scans' every hit is
    aligned, not the few points kept for matching, so that more pairs of keyframes overlap
    enough to judge; those that still do not (a corridor walked back the other way) are refused:
    on freiburg-079 the closures that could not be judged were the ones the scans contradict."""
    target = LineCloud(old.rays.hits)
    aligned = align(target, newest.rays.hits, measured)
    if aligned is None:
        return False
    pose, hessian = aligned
    return within_check(pose, measured, config) and \
        not fits_as_well_elsewhere(target, newest.points, pose, hessian, window, config, fit_share)


def fits_as_well_elsewhere(target, points, pose, hessian, window, config, fit_share=ALIAS_FIT_SHARE):
    """Whether `points`, aligned from further either way along the direction the alignment pins
    least (a corridor's length), lie on the `target` scan's lines at another pose almost as well
    (`fit_share`) as at `pose`; the starts reach as far as the loop search did (`window`).
    Along a corridor ICP stops where a few door frames line up: on infinite-corridor (odometry
    seeds 2-4) it agreed with closures 0.3-0.6 m along the corridor from where the scans fit
    best, and the graph took them; a search widened to 5 m found doors 4.7 and 9 m along that
    fit nearly as well. A closure whose scans fit as well elsewhere cannot say where the robot is."""
    _, directions = np.linalg.eigh(hessian[:2, :2])
    along = directions[:, 0]
    fit = target.points_on_lines(points, pose)
    steps = int(max(ALIAS_MIN_REACH, window) / ALIAS_SHIFT_STEP + 1e-9)
    for shift in ALIAS_SHIFT_STEP * np.arange(1, steps + 1):
        for sign in (-1.0, 1.0):
            start = (pose[0] + sign * shift * along[0], pose[1] + sign * shift * along[1], pose[2])
            other = align(target, points, start, ALIAS_ICP_ITERATIONS)
            if other is not None and not within_check(other[0], pose, config) and \
                    target.points_on_lines(points, other[0]) >= fit_share * fit:
                return True
    return False


class LoopCloser:
    """Closes loops in a SLAM's pose graph as keyframes join it (see the module's docstring)."""

    def __init__(self, config):
        self.config = config  # slam.SlamConfig (its loop_* parameters above all)
        self.drift_path = DriftPath()
        self.closures = []    # (old keyframe, new keyframe, new seen from old, score), accepted
        self.rejected = 0     # accepted, then taken out again as the optimised graph contradicts them
        self._pending = []    # closures waiting for one that agrees
        self._last_attempt = -(10 ** 9)
        self.deferred = False  # the graph holds closures' edges it has not been optimised with

    def keyframe_added(self, keyframes, graph, optimize):
        """After the newest of `keyframes` joined `graph` (node per keyframe): look for a loop every
        loop_attempt_every keyframes, and close it; `optimize()` optimises the graph and lets the
        SLAM follow its keyframes."""
        step = keyframes[-1].travel - keyframes[-2].travel if len(keyframes) > 1 else 0.0
        self.drift_path.extend(step)
        newest = len(keyframes) - 1
        if newest - self._last_attempt >= self.config.loop_attempt_every:
            closure, window = self._search(keyframes, graph, newest)
            if closure is not None and keyframes_agree(keyframes[closure.old], keyframes[newest], closure.measured,
                                                       self.config, window):
                self.consider(closure, keyframes, graph, optimize)

    def _search(self, keyframes, graph, newest):
        """The newest keyframe matched against the old ones near it, and the search's half-width;
        (None, 0) when none is near or the match is poor."""
        config = self.config
        oldest_local = newest - config.local_map_keyframes
        if oldest_local <= 0:
            return None, 0.0
        travel = np.array([keyframe.travel for keyframe in keyframes[:oldest_local]])
        path = keyframes[newest].travel - travel
        windows = self.drift_path.windows(config, oldest_local)
        poses = graph.poses[:oldest_local]
        current = tuple(graph.poses[newest])
        gaps = np.hypot(poses[:, 0] - current[0], poses[:, 1] - current[1])
        eligible = (path >= config.loop_min_travel) & \
            (gaps <= config.loop_search_radius + windows - config.loop_window_xy)
        if not eligible.any():
            return None, 0.0
        self._last_attempt = newest
        candidate = int(np.flatnonzero(eligible)[np.argmin(gaps[eligible])])
        window = float(windows[candidate])
        members = self._submap_members(candidate, window, eligible, gaps)
        cloud = self._recent_cloud(keyframes, graph, newest)
        if len(cloud) < 20:
            return None, 0.0
        matcher = self._submap_matcher(keyframes, graph, members, current, cloud, window)
        result = matcher.match(cloud, current, window, config.loop_window_theta, min_score=config.loop_min_score)
        if result.score < config.loop_min_score:
            return None, 0.0
        pose = matcher.refine(cloud, result.pose).pose
        old = nearest_view(graph.poses, members, pose)
        return LoopClosure(old, newest, relative(tuple(graph.poses[old]), pose), result.score,
                           compose(pose, inverse(current)), current), window

    def _submap_members(self, candidate, window, eligible, gaps):
        """The old keyframes the loop search matches against: those along the path around the
        candidate or, when the search has widened, the eligible ones nearest the newest keyframe
        (`eligible` and `gaps` are per old keyframe)."""
        config = self.config
        if window <= config.loop_window_xy:
            return [index for index in range(candidate - config.loop_submap_keyframes,
                                             candidate + config.loop_submap_keyframes + 1)
                    if 0 <= index < len(eligible)]
        near = np.flatnonzero(eligible & (gaps <= window + WIDE_SUBMAP_MARGIN))
        return sorted(near[np.argsort(gaps[near])[:WIDE_SUBMAP_KEYFRAMES]].tolist())

    def _recent_cloud(self, keyframes, graph, newest):
        """The last loop_cloud_keyframes keyframes' points, seen from the newest."""
        current = tuple(graph.poses[newest])
        parts = []
        for index in range(max(0, newest - self.config.loop_cloud_keyframes + 1), newest + 1):
            seen_from_current = relative(current, tuple(graph.poses[index]))
            parts.append(transform_points(seen_from_current, keyframes[index].points))
        cloud = voxel_filter(np.concatenate(parts), self.config.resolution)
        limit = 2 * self.config.match_points
        if len(cloud) > limit:
            cloud = cloud[np.linspace(0, len(cloud) - 1, limit).astype(int)]
        return cloud

    def _submap_matcher(self, keyframes, graph, members, current, cloud, window):
        """A matcher over the old keyframes' points where the cloud can fall in the loop search's
        window, with room for the coarsest maxima's blocks and the field's spread."""
        resolution = self.config.loop_match_resolution
        low, high = searched_cells(cloud, current, window, self.config.loop_window_theta, resolution)
        margin = (1 << LEVELS) + FIELD_RADIUS
        low, high = low - margin, high + margin
        size = high - low + 1
        hits = np.concatenate([transform_points(tuple(graph.poses[index]), keyframes[index].points)
                               for index in members])
        cells, sums, counts = hit_cells(hits, resolution)
        cells -= low
        inside = ((cells >= 0) & (cells < size)).all(axis=1)
        field = sparse_likelihood_field((size[1], size[0]), cells[inside, 1], cells[inside, 0],
                                        np.ones(inside.sum()), sums[inside] / counts[inside, None] - 0.5)
        return GridMatcher(field, low, resolution, levels=LEVELS)

    def consider(self, closure, keyframes, graph, optimize):
        """Close loops only on closures that agree: one match can be fooled by corridors that look
        alike, two from different places rarely agree on the same wrong correction. Accepted
        closures that the optimised graph then contradicts are taken out again."""
        config = self.config
        self._pending = [pending for pending in self._pending
                         if closure.newest - pending.newest <= config.loop_pending_keyframes]
        agreeing = [pending for pending in self._pending if pending.agrees_with(closure, config)]
        if not agreeing:
            self._pending.append(closure)
            return
        self._pending = [pending for pending in self._pending if pending not in agreeing]
        accepted = agreeing + [closure]
        information = diagonal_information(config.loop_sigma_xy, config.loop_sigma_theta)
        for each in accepted:
            graph.add_edge(each.old, each.newest, each.measured, information, robust=True)
        if any(each.moves_map(config) for each in accepted):
            optimize()
            self.deferred = False
            self._drop_contradicted(accepted, graph, optimize)
        else:
            self.deferred = True
        kept = [each for each in accepted if each.edge_in(graph)]
        self.closures.extend((each.old, each.newest, each.measured, each.score) for each in kept)
        travel = np.array([keyframe.travel for keyframe in keyframes])
        for each in kept:
            self.drift_path.shorten(travel, each)

    def optimize_deferred(self, optimize):
        """Optimise the graph with the closures that each moved the map too little to pay for it."""
        if self.deferred:
            optimize()
            self.deferred = False

    def _drop_contradicted(self, accepted, graph, optimize):
        errors = graph.edge_errors()
        index = {id(edge): position for position, edge in enumerate(graph.edges)}
        wrong = [edge for edge in graph.edges if edge.robust and any(
            each.is_edge(edge) for each in accepted) and self._contradicts(errors[index[id(edge)]])]
        if wrong:
            graph.edges = [edge for edge in graph.edges if edge not in wrong]
            self.rejected += len(wrong)
            optimize()

    def _contradicts(self, error):
        return math.hypot(error[0], error[1]) > self.config.loop_residual_xy or \
            abs(error[2]) > self.config.loop_residual_theta
