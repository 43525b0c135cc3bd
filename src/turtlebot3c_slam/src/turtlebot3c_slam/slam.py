"""2-D laser SLAM: scan-to-map tracking, keyframes in a pose graph, loop closure. Pure numpy; no rospy.

Use::

    slam = Slam(SlamConfig())                      # or SlamConfig.from_dict({...})
    pose = slam.add_scan(stamp, ranges, geometry, odom_pose)   # per LaserScan (+ motion: scan_deskew)
    slam.map_to_odom                               # (x, y, yaw) for the map -> odom transform
    slam.occupancy_map()                           # map_files.OccupancyMap (100 / 0 / -1)
    slam.trajectory()                              # [(stamp, x, y, yaw)] per scan, after loop closures
    slam.refine()                                  # at the end of a session (scan_refinement)

How it works:
- *Tracking*: odometry since the last scan predicts the pose, corrected by how odometry was
  seen to err in the earlier matches (odometry_calibration: distances and turns that read
  long or short, a heading that drifts; a corridor otherwise takes the length odometry
  reads). The scan is matched against a local map made of the hits of the last
  `local_map_keyframes` keyframes (a grid that adds each new keyframe's hits and takes
  back the oldest's; like Karto's, it traces no free space: matching needs only the
  obstacles, and tracing ~10^5 cells per keyframe at 2.5 cm took a quarter of the time while
  the real-data figures were no better for it), searching a window around the prediction
  that is as wide as odometry may be wrong: 3 sigma, where sigma grows with the distance,
  turn and time since the last good match (a real robot's wheels slip, scans may come a
  metre apart). The correlative search (scan_matcher, branch and bound) finds the cell and
  angle step; a Gauss-Newton step on the interpolated field refines it below a cell. A
  doubtful match (score below `match_wide_score`) is searched again over the widest window (a
  slip), and the better of the two kept. So are windows around the pose the robot reaches
  going on at the speed of its last two matched scans, and between it and the prediction,
  when that pose lies outside the first window (a slip: the wheels read the step short or
  long, the robot went on at its speed or part way). Below `match_min_score`, the scan
  keeps odometry, and the next scan searches wider. It does not become a keyframe either
  (unless poor matches go on), so a guessed pose never draws the local map that the next
  scans match against.
- *Keyframes*: after `keyframe_distance` metres or `keyframe_angle` radians, the scan becomes
  a node of the pose graph, chained to the previous keyframe by the tracked relative pose.
- *Loop closure* (loop_closure): a new keyframe near an old part of the trajectory is matched
  against the old keyframes there, over a window as wide as the map may have drifted along the
  path between them; a match the two keyframes' own scans confirm, and a second one that moves
  the map alike, close the loop. The maps are then rebuilt from every keyframe at its new
  pose, so the loop closes without doubled walls.
- The map frame is the odometry frame at the first scan (map -> odom starts as identity).
"""
import collections
import copy
import math

import numpy as np

from turtlebot3c_common.parameter_files import is_finite_number
from turtlebot3c_common.se2 import compose, distance, inverse, poses_within, relative

from . import scan_refinement
from .loop_closure import LoopCloser
from .occupancy_grid import LogOddsGrid
from .odometry_calibration import OdometryCalibration, firmness_along_heading
from .pose_graph import PoseGraph, diagonal_information
from .scan_matcher import FIELD_RADIUS, GridMatcher, searched_cells, sparse_likelihood_field
from .slam_scan import scan_rays, voxel_filter

# Names turtlebot3_slam's `slam_methods` argument takes that this SLAM stands in for, with the
# node name upstream gives each (its CI looks for turtlebot3_slam_gmapping).
SLAM_METHODS = collections.OrderedDict([("gmapping", "turtlebot3_slam_gmapping"), ("karto", "slam_karto")])


def check_slam_method(name):
    """The node name for a slam_methods value; ValueError naming the known ones otherwise."""
    if name not in SLAM_METHODS:
        raise ValueError("unknown slam_methods {!r}: known methods are {} (each runs turtlebot3c's own "
                         "SLAM)".format(name, ", ".join(SLAM_METHODS)))
    return SLAM_METHODS[name]


class SlamConfig:
    """SLAM parameters; `SlamConfig.from_dict(params)` rejects unknown names and bad values."""

    DEFAULTS = collections.OrderedDict([
        ("resolution", 0.05),             # m per cell of the published map
        ("match_resolution", 0.025),      # m per cell of the local map scans are tracked against
        # m; hits beyond count as free rays up to here. A convention hall's walls are half of
        # its hits and mostly 8-16 m off; the LDS-01/02 reach less than this anyway.
        ("usable_range", 16.0),
        ("hit_log_odds", 0.85),
        ("free_log_odds", -0.4),
        # A keyframe costs a trace into the map, a new tracking matcher and a loop search;
        # on 5 Hz scans, keyframes 0.3 m apart track as precisely as 0.2 m apart, ~20 % faster.
        ("keyframe_distance", 0.3),       # m of motion between keyframes
        ("keyframe_angle", 0.3),          # rad of rotation between keyframes
        ("local_map_keyframes", 20),      # keyframes in the tracking map (~6 m of path at 5 Hz)
        # How far odometry's prediction may be off (1 sigma): after a good match, and growing
        # with the distance, turn and time since the last good match. Tracking searches
        # 3 sigma around the prediction, up to the max windows.
        ("match_sigma_xy", 0.03),         # m
        ("match_sigma_theta", 0.03),      # rad
        ("odometry_error_distance", 0.1),   # m per m travelled
        ("odometry_error_turn", 0.12),    # rad per rad turned
        ("odometry_error_heading", 0.03),  # rad per m travelled
        ("odometry_error_time", 0.01),    # m and rad per s (a slipping wheel)
        # m of path after which a step's evidence counts half in learning how odometry errs
        # (odometry_calibration), by which each prediction is corrected
        ("odometry_scale_memory", 20.0),
        # m and rad per sqrt(m + rad) of path: how odometry, so corrected, still errs (a random
        # walk). The refinement at the end weighs its steps between keyframes by it.
        ("odometry_walk_xy", 0.01),
        ("odometry_walk_theta", 0.005),
        ("match_window_max_xy", 1.0),     # m
        ("match_window_max_theta", 0.7),  # rad
        # Below: keep odometry, and search wider next scan. A blinded LIDAR's garbage scores
        # 0.01-0.03; a right match of sparse real scans that see much new ground, 0.08-0.2.
        ("match_min_score", 0.1),
        # Below: search the widest window as well, and keep the better match
        ("match_wide_score", 0.2),
        ("match_points", 300),            # at most this many scan points are matched
        ("loop_search_radius", 3.0),      # m between a new keyframe and an old one to try closing
        ("loop_min_travel", 6.0),         # m of path between them
        ("loop_window_xy", 1.0),          # m, loop-closure search half-width, at least
        # m per m of path between an old keyframe and the newest, a closed loop counting as a
        # shortcut: how far the map may have drifted between them. The search widens by as much,
        # up to the max; aces, fhw, acapulco and infinite-corridor drifted 3-10 m at 1-3 %.
        ("loop_drift", 0.03),
        ("loop_window_max_xy", 10.0),     # m
        ("loop_window_theta", 0.35),      # rad
        # m per cell of the loop search's submap. Its old keyframes sit a few cm off each other
        # after a long loop; at 2.5 cm a right match scored too little (acapulco: no loop closed).
        ("loop_match_resolution", 0.05),
        ("loop_min_score", 0.55),         # mean likelihood needed to consider a closure
        ("loop_check_xy", 0.1),           # m: the two keyframes' own scans must agree this well...
        ("loop_check_theta", 0.02),       # rad: ...with a closure's relative pose between them
        ("loop_agreement_xy", 0.15),      # m: two closures agree when they move the map alike
        ("loop_agreement_theta", 0.03),   # rad
        ("loop_pending_keyframes", 10),   # keyframes a closure waits for one that agrees
        ("loop_residual_xy", 0.2),        # m: a closure the optimised graph misses by more is dropped
        ("loop_residual_theta", 0.035),   # rad
        ("loop_submap_keyframes", 12),    # old keyframes each side of the candidate in its submap
        ("loop_cloud_keyframes", 6),      # recent keyframes whose points form the query
        ("loop_attempt_every", 2),        # keyframes between loop-closure attempts
        ("odometry_sigma_xy", 0.02),      # m, sequential edge uncertainty
        ("odometry_sigma_theta", 0.01),   # rad
        ("loop_sigma_xy", 0.05),          # m, loop edge uncertainty
        ("loop_sigma_theta", 0.02),       # rad
    ])
    INTEGERS = ("local_map_keyframes", "match_points", "loop_submap_keyframes", "loop_cloud_keyframes",
                "loop_attempt_every", "loop_pending_keyframes")

    def __init__(self, **values):
        unknown = sorted(set(values) - set(self.DEFAULTS))
        if unknown:
            raise ValueError("unknown SLAM parameter(s) {}; known: {}".format(
                ", ".join(unknown), ", ".join(self.DEFAULTS)))
        for name, default in self.DEFAULTS.items():
            value = values.get(name, default)
            if not is_finite_number(value):
                raise ValueError(f"SLAM parameter {name} must be a finite number, got {value!r}")
            if name in self.INTEGERS:
                if int(value) != value or value < 1:
                    raise ValueError(f"SLAM parameter {name} must be a positive integer, got {value!r}")
                value = int(value)
            elif name != "free_log_odds" and value <= 0:
                raise ValueError(f"SLAM parameter {name} must be positive, got {value!r}")
            setattr(self, name, value)
        if self.free_log_odds >= 0:
            raise ValueError(f"SLAM parameter free_log_odds must be negative, got {self.free_log_odds!r}")
        if self.loop_window_max_xy < self.loop_window_xy:
            raise ValueError(f"SLAM parameter loop_window_max_xy ({self.loop_window_max_xy!r}) must be at least "
                             f"loop_window_xy ({self.loop_window_xy!r})")

    @classmethod
    def from_dict(cls, values):
        return cls(**dict(values))

    def as_dict(self):
        return collections.OrderedDict((name, getattr(self, name)) for name in self.DEFAULTS)


# m + rad: the least path an odometry step is weighed over, so a robot standing still does not pin its keyframes
WALK_FLOOR = 0.01


class MapRebuild:
    """The map redrawn from keyframes at given poses (see Slam.map_rebuild)."""

    def __init__(self, grid, keyframes, optimizations):
        self.grid = grid
        self.keyframes = keyframes          # [(ScanRays, pose)]
        self.optimizations = optimizations  # the Slam's optimisation count when taken

    def run(self):
        for rays, pose in self.keyframes:
            self.grid.add_scan(rays, pose)
        return self.grid


class RedrawBudget:
    """When the map may next be redrawn from every keyframe: a redraw that took `seconds` is
    followed by at least seconds * (1 - share) / share without one, so redraws take at most
    `share` of the time whatever the map's size. A floor of a few thousand keyframes takes
    seconds to redraw, and loop closures come every few seconds there: redrawing after each
    would leave no CPU to map with on a robot's small computer."""

    def __init__(self, share=0.2):
        self.share = share
        self.next_allowed = -math.inf

    def allows(self, now):
        return now >= self.next_allowed

    def spent(self, seconds, now):
        self.next_allowed = now + seconds * (1.0 - self.share) / self.share


class UnmatchedMotion:
    """Odometry's motion since the last scan that matched well: what its error grows with."""

    def __init__(self, stamp=None):
        self.distance = 0.0  # m
        self.turn = 0.0      # rad
        self.seconds = 0.0
        self.stamp = stamp

    def add(self, delta, stamp):
        self.distance += math.hypot(delta[0], delta[1])
        self.turn += abs(delta[2])
        if self.stamp is not None:
            self.seconds += max(0.0, stamp - self.stamp)
        self.stamp = stamp


def positions_towards(start, end, spacing):
    """Positions from `start` along the line to `end`, `start` first and `end` left out, at most
    `spacing` apart and from `end`: windows of half that width around them and `end` leave no gap."""
    steps = max(1, int(math.ceil(distance(start, end) / spacing)))
    return [(end[0] + (start[0] - end[0]) * k / steps, end[1] + (start[1] - end[1]) * k / steps)
            for k in range(steps, 0, -1)]


class Keyframe:
    def __init__(self, stamp, rays, points, travel, odom):
        self.stamp = stamp
        self.rays = rays        # ScanRays in the robot frame, to rebuild maps
        self.points = points    # down-sampled hits in the robot frame, to match
        self.travel = travel    # m of path from the first scan
        self.odom = odom        # the odometry's pose (odom frame) at the keyframe's scan


class Slam:
    POOR_STREAK_LIMIT = 2
    STEADY_MARGIN = 1.25  # times the score around odometry's prediction (_track)
    # m around what a scan can reach in its search window that the tracking map also covers: the
    # next scans, until the next keyframe redraws the map, reuse it while they stay inside. At
    # least the branch and bound's coarsest block plus the field's spread (0.25 m), so the field
    # and its maxima where the points fall are what a map without edges would give.
    TRACKING_MAP_MARGIN = 0.5
    TRACKING_LEVELS = 3  # coarser maxima grids of the tracking search's branch and bound

    def __init__(self, config=None):
        self.config = config or SlamConfig()
        self.graph = PoseGraph()
        self.keyframes = []
        self.local_grid = self._new_grid(self.config.match_resolution)
        self.local_updates = collections.deque()
        self.global_grid = self._new_map_grid()
        self._global_dirty = False
        self._optimizations = 0
        self._local_version = 0
        self._tracking = None      # (GridMatcher, low, high, version)
        self._scans = []           # (stamp, keyframe index, pose relative to it)
        self.pose = None
        self.odom = None
        self.travel = 0.0
        self.map_version = 0       # changes whenever the map may have changed
        self.poor_matches = 0
        self._poor_streak = 0      # poorly matched scans in a row
        self._unmatched = UnmatchedMotion()
        self._matched = True       # the last scan was matched (the first one's pose is odometry's)
        self._stamp = None         # the last scan's
        self._velocity = None      # (x, y) m/s in the robot's frame between the last two scans, when both matched
        self.odometry_calibration = OdometryCalibration(
            self.config.odometry_scale_memory, self.config.odometry_error_distance, self.config.odometry_error_turn,
            self.config.odometry_error_heading)
        self.loops = LoopCloser(self.config)

    def _new_grid(self, resolution, cell_shift=0.0):
        return LogOddsGrid(resolution, self.config.hit_log_odds, self.config.free_log_odds, cell_shift)

    def _new_map_grid(self):
        """The published map's grid, a cell centred on the map frame's origin: walls that lie on
        a lattice of the resolution from there (as the simulated worlds' do from their spawn
        poses) are then drawn in the cells centred on them. With cell corners there instead,
        which cell a wall's hits fall in is decided by their noise, and every such wall is drawn
        a fraction of a cell to the same side. Elsewhere the choice makes no difference."""
        return self._new_grid(self.config.resolution, cell_shift=0.5)

    # --- per scan -------------------------------------------------------------------------

    def add_scan(self, stamp, ranges, geometry, odom_pose, motion=None):
        """Process one scan with the odometry pose (odom frame) of the robot at its time; returns the map pose.

        A scan measured over time comes with `motion` (scan_deskew.beam_motion), and `stamp` and
        `odom_pose` are then those of its reference time (scan_deskew.reference_time).
        """
        rays = scan_rays(geometry, ranges, self.config.usable_range, motion)
        points = self._matching_points(rays.hits)
        odom_pose = tuple(float(v) for v in odom_pose)
        if not self.keyframes:
            self.pose, self.odom, self._stamp = odom_pose, odom_pose, stamp
            self._add_keyframe(stamp, rays, points)
            self._scans.append((stamp, 0, (0.0, 0.0, 0.0)))
            return self.pose
        delta = relative(self.odom, odom_pose)
        self.travel += math.hypot(delta[0], delta[1])
        self._unmatched.add(delta, stamp)
        predicted = compose(self.pose, self.odometry_calibration.corrected(delta))
        previous, previous_matched, seconds = self.pose, self._matched, stamp - self._stamp
        self.pose, self._matched, slipped = self._track(points, predicted, self._steady_position(seconds))
        self._velocity = None
        if previous_matched and self._matched:
            matched = relative(previous, self.pose)
            if not slipped:  # a slip tells nothing of how odometry errs from step to step
                self._learn_odometry(delta, matched, points)
            if seconds > 0:
                self._velocity = (matched[0] / seconds, matched[1] / seconds)
        self.odom, self._stamp = odom_pose, stamp
        last = len(self.keyframes) - 1
        moved = relative(self.graph.poses[last], self.pose)
        if (math.hypot(moved[0], moved[1]) >= self.config.keyframe_distance or
                abs(moved[2]) >= self.config.keyframe_angle) and self._may_add_keyframe():
            self._add_keyframe(stamp, rays, points)
            last = len(self.keyframes) - 1
        self._scans.append((stamp, last, relative(tuple(self.graph.poses[last]), self.pose)))
        return self.pose

    def _learn_odometry(self, delta, matched, points):
        self.odometry_calibration.learn_turn(delta, matched)
        # A step odometry read as no motion teaches the distance nothing: spare its scan's k-d
        # tree (a robot standing still, or turning on the spot, while mapping runs).
        if delta[0] or delta[1]:
            self.odometry_calibration.learn_distance(delta, matched, firmness_along_heading(points))

    @property
    def map_to_odom(self):
        if self.pose is None:
            return (0.0, 0.0, 0.0)
        return compose(self.pose, inverse(self.odom))

    def _matching_points(self, hits):
        points = voxel_filter(hits, self.config.resolution)
        if len(points) > self.config.match_points:
            points = points[np.linspace(0, len(points) - 1, self.config.match_points).astype(int)]
        return points

    def _steady_position(self, seconds):
        """Where the robot is if it went on at the speed it had between the last two scans (None: unknown)."""
        if self._velocity is None or seconds <= 0:
            return None
        return compose(self.pose, (self._velocity[0] * seconds, self._velocity[1] * seconds, 0.0))[:2]

    def _track(self, points, predicted, steady_position=None):
        """The scan's pose, whether it was matched (False: the prediction kept), and whether it was
        found where the robot's speed took it rather than near odometry's prediction (a slip)."""
        if len(points) < 10 or not self.local_updates:
            return predicted, False, False
        window_xy, window_theta = self._tracking_window()
        matcher, result = self._search(points, predicted, window_xy, window_theta)
        slipped = False
        if steady_position is not None and distance(steady_position, predicted) > window_xy:
            # A slip reads a step short (or a spinning wheel long) while the robot goes on at its
            # speed: belgioioso, severe, 1 Hz scans in a corridor, a 1.0 m step read as 0.43 m. In
            # the window around that, a pose 0.5 m short scored 0.45; the truth, outside it, 0.62.
            # But a robot also speeds up (orebro: 1 m, then 2.1 m a scan, odometry right), and along
            # a corridor a pose a metre short scored 0.45 against the truth's 0.43: only a clearly
            # better match overrules odometry. The heading stays odometry's: a robot turning back
            # and forth does not go on turning (fhw).
            # A slip may also leave the robot part way between (orebro, severe: a 3.0 m step read
            # as 4.2 m, the speed saying 2.0 m; the truth lay outside both windows, and the scan
            # kept odometry's guess, 1.6 m off). Windows from the speed's pose towards odometry's
            # cover the whole way, each taken only if clearly better than the best so far.
            for position in positions_towards(steady_position, predicted, 2.0 * window_xy):
                centre = (position[0], position[1], predicted[2])
                slip_matcher, slip_result = self._search(points, centre, window_xy, window_theta)
                if slip_result.score > self.STEADY_MARGIN * result.score:
                    matcher, result, slipped = slip_matcher, slip_result, True
        # A match_wide_score set below match_min_score must not spare a rejected match its wide search.
        if result.score < max(self.config.match_wide_score, self.config.match_min_score):
            # A slip can throw the robot further than 3 sigma (fhw, severe: 0.44 m sideways in
            # one scan against a 0.31 m window, and the guess drawn into the map turned the rest
            # of the log 12 degrees). Within the window the best may then be a doubtful match
            # that is wrong (acapulco, severe: a slip read as a 13-degree turn left the truth
            # out, and a pose 20 degrees off scored 0.13): search the widest window once.
            wide_matcher, wide = self._search(points, predicted, self.config.match_window_max_xy,
                                              self.config.match_window_max_theta)
            if wide.score > result.score:
                matcher, result, slipped = wide_matcher, wide, False
        if result.score < self.config.match_min_score:
            self.poor_matches += 1
            self._poor_streak += 1
            return predicted, False, False
        self._poor_streak = 0
        self._unmatched = UnmatchedMotion(self._unmatched.stamp)
        return matcher.refine(points, result.pose).pose, True, slipped

    def _search(self, points, predicted, window_xy, window_theta):
        """The tracking map's best match for the points within the window around `predicted`."""
        matcher = self._tracking_matcher(points, predicted, window_xy, window_theta)
        # A weak prior: it settles ties (a corridor's length) without outvoting the scan.
        return matcher, matcher.match(points, predicted, window_xy, window_theta,
                                      prior_sigmas=(window_xy, window_theta))

    def _may_add_keyframe(self):
        """Not from a scan that matched poorly: its pose is odometry's guess, and drawn into the
        local map it would mislead the next scans' matching (a turn taken 25 degrees wrong on a
        real log). After POOR_STREAK_LIMIT poor scans in a row, the map must follow anyway."""
        return self._poor_streak == 0 or self._poor_streak >= self.POOR_STREAK_LIMIT

    def _tracking_window(self):
        """Search half-widths (m, rad): 3 sigma of how far odometry may have drifted since the last good match."""
        config, motion = self.config, self._unmatched
        sigma_xy = config.match_sigma_xy + config.odometry_error_distance * motion.distance + \
            config.odometry_error_time * motion.seconds
        sigma_theta = config.match_sigma_theta + config.odometry_error_turn * motion.turn + \
            config.odometry_error_heading * motion.distance + config.odometry_error_time * motion.seconds
        return min(3 * sigma_xy, config.match_window_max_xy), min(3 * sigma_theta, config.match_window_max_theta)

    def _tracking_matcher(self, points, predicted, window_xy, window_theta):
        """A matcher over the part of the local map the points can fall on within the window: the
        field is built afresh at each keyframe, and over a 180-degree scan's box rather than its
        range's full circle it takes half the time or less."""
        resolution = self.config.match_resolution
        need_low, need_high = searched_cells(points, predicted, window_xy, window_theta, resolution)
        cached = self._tracking
        if cached is not None and cached[3] == self._local_version and (need_low >= cached[1]).all() \
                and (need_high <= cached[2]).all():
            return cached[0]
        margin = int(math.ceil(self.TRACKING_MAP_MARGIN / resolution))
        low, high = need_low - margin, need_high + margin
        size = high - low + 1
        field = sparse_likelihood_field((size[1], size[0]), *self.local_grid.obstacles(low, size))
        matcher = GridMatcher(field, low, resolution, levels=self.TRACKING_LEVELS)
        # Near its edge the field misses obstacles beyond it (it spreads FIELD_RADIUS cells, the
        # coarsest maxima span 2^levels): later scans may use only the inside.
        edge = (1 << self.TRACKING_LEVELS) + FIELD_RADIUS
        self._tracking = (matcher, low + edge, high - edge, self._local_version)
        return matcher

    # --- keyframes and the maps -----------------------------------------------------------

    def _add_keyframe(self, stamp, rays, points):
        index = self.graph.add_node(self.pose)
        self.keyframes.append(Keyframe(stamp, rays, points, self.travel, self.odom))
        if index > 0:
            previous = tuple(self.graph.poses[index - 1])
            self.graph.add_edge(index - 1, index, relative(previous, self.pose), diagonal_information(
                self.config.odometry_sigma_xy, self.config.odometry_sigma_theta))
        update = self.local_grid.hits_of(rays, self.pose)
        self.local_grid.apply(update)
        self.local_updates.append((index, update))
        if len(self.local_updates) > self.config.local_map_keyframes:
            self.local_grid.apply(self.local_updates.popleft()[1], sign=-1)
            if index % self.config.local_map_keyframes == 0:
                self._compact_local_map()
        if not self._global_dirty:
            self.global_grid.add_scan(rays, self.pose)
        self._local_version += 1
        self.map_version += 1
        self.loops.keyframe_added(self.keyframes, self.graph, self._optimize)

    def _compact_local_map(self):
        """The local map's array afresh from the keyframes it holds. Its array only grows, and a
        long session would leave it as wide as the whole floor at the fine matching resolution:
        gigabytes on a corridor a kilometre long, for the last few metres of keyframes."""
        self.local_grid = self._empty_local_grid()
        for _, update in self.local_updates:
            self.local_grid.apply(update)
        self._local_version += 1

    def _empty_local_grid(self):
        """A new local map grid, already as large as its keyframes' updates: drawn in one by one,
        they would grow it (a copy of the whole array) several times each time."""
        grid = self._new_grid(self.config.match_resolution)
        covered = [update.bounds() for _, update in self.local_updates if update.bounds() is not None]
        if covered:
            grid.reserve(np.min([low for low, _ in covered], axis=0), np.max([high for _, high in covered], axis=0))
        return grid

    def _rebuild_local_map(self):
        self.local_grid = self._empty_local_grid()
        rebuilt = collections.deque()
        for index, _ in self.local_updates:
            update = self.local_grid.hits_of(self.keyframes[index].rays, tuple(self.graph.poses[index]))
            self.local_grid.apply(update)
            rebuilt.append((index, update))
        self.local_updates = rebuilt
        self._local_version += 1

    def occupancy_map(self):
        """The whole map so far as a map_files.OccupancyMap (cells 100 / 0 / -1)."""
        rebuild = self.map_rebuild()
        if rebuild is not None:
            rebuild.run()
            self.adopt(rebuild)
        return self.global_grid.to_occupancy_map()

    @property
    def map_outdated(self):
        """True after a loop closure until the map is redrawn (occupancy_map() or adopt())."""
        return self._global_dirty

    def map_rebuild(self):
        """None while the map is up to date; after a loop closure moved keyframes, a MapRebuild.

        Redrawing every keyframe takes a while in a big map: a node can run() the rebuild
        without holding up scan processing, then hand it back with adopt().
        """
        if not self._global_dirty:
            return None
        keyframes = [(keyframe.rays, tuple(self.graph.poses[index])) for index, keyframe in enumerate(self.keyframes)]
        return MapRebuild(self._new_map_grid(), keyframes, self._optimizations)

    def adopt(self, rebuild):
        """Take a finished MapRebuild as the map (adding keyframes made since); False if a new loop
        closure has moved the keyframes again in the meantime."""
        if not self._global_dirty or rebuild.optimizations != self._optimizations:
            return False
        for index in range(len(rebuild.keyframes), len(self.keyframes)):
            rebuild.grid.add_scan(self.keyframes[index].rays, tuple(self.graph.poses[index]))
        self.global_grid = rebuild.grid
        self._global_dirty = False
        return True

    def trajectory(self):
        """(stamp, x, y, yaw) of every scan, on the optimised keyframe poses."""
        return [(stamp,) + compose(tuple(self.graph.poses[index]), offset)
                for stamp, index, offset in self._scans]

    # --- when the graph moves its keyframes (loop closure, refinement) ---------------------

    def _optimize(self):
        newest = len(self.keyframes) - 1
        before = tuple(self.graph.poses[newest])
        self.graph.optimize()
        self._keyframes_moved(before)

    def optimize_deferred_closures(self):
        """Before a map is published or saved: take in the loop closures that each moved the map
        by less than half a cell (LoopCloser.optimize_deferred), which redraws it."""
        self.loops.optimize_deferred(self._optimize)

    def refine(self):
        """At the end of a session: every keyframe where its scan agrees best with those of the
        keyframes near it (scan_refinement), on top of the graph's own edges and odometry's steps
        between keyframes; the maps follow."""
        if len(self.keyframes) < 2:
            return
        before = tuple(self.graph.poses[-1])
        clouds = [scan_refinement.scan_cloud(keyframe.rays.hits) for keyframe in self.keyframes]
        self.graph.poses = scan_refinement.refine(self._graph_with_odometry(), clouds)
        self._keyframes_moved(before)

    def _graph_with_odometry(self):
        """A copy of the graph with odometry's step between each two keyframes as an edge, corrected
        as the calibration learnt by the end says, weighed by the random walk odometry keeps, and
        robust (a slip). Where a corridor leaves the scans loose along it, or a turn a tracking
        cell's worth of heading, odometry holds the steps together: on the Radish logs the relations
        error fell on 31 of 33 runs and rose on none by over 0.0002 m (acapulco, mild: 0.077 to 0.074 m;
        docs/benchmarks.md).
        A step further from the tracked one than tracking's widest window is no measurement (the
        odometry was reset, a wheel spun in place): it is left out, as even robust it would pull."""
        graph = copy.deepcopy(self.graph)
        config, calibration = self.config, self.odometry_calibration
        for index in range(1, len(self.keyframes)):
            step = calibration.corrected(relative(self.keyframes[index - 1].odom, self.keyframes[index].odom))
            tracked = relative(tuple(graph.poses[index - 1]), tuple(graph.poses[index]))
            if not poses_within(tracked, step, config.match_window_max_xy, config.match_window_max_theta):
                continue
            path = math.hypot(step[0], step[1]) + abs(step[2]) + WALK_FLOOR
            information = diagonal_information(config.odometry_walk_xy * math.sqrt(path),
                                               config.odometry_walk_theta * math.sqrt(path))
            graph.add_edge(index - 1, index, step, information, robust=True)
        return graph

    def _keyframes_moved(self, newest_before):
        """After the graph moved its keyframes: the pose follows the newest, the maps are redrawn."""
        newest = len(self.keyframes) - 1
        self.pose = compose(tuple(self.graph.poses[newest]), relative(newest_before, self.pose))
        self._rebuild_local_map()
        self._global_dirty = True
        self._optimizations += 1
        self.map_version += 1
