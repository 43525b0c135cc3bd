"""Adaptive Monte Carlo localisation: a particle filter over (x, y, yaw) in the map frame.

- motion: the odometry motion model for a differential drive (rot1, trans, rot2 with
  noise alpha1..alpha4, Probabilistic Robotics §5.4), applied once the robot has moved
  update_min_d or turned update_min_a since the last filter update, as ROS amcl does; a
  share of the particles takes each step as a wheel slip;
- sensor: the likelihood-field model (likelihood_field.py) on a subset of the beams; a
  scan that carries a tracking estimate far beyond the motion noise to where it fits
  poorly does not weigh;
- resampling: low-variance, with the particle count chosen by KLD sampling (Fox 2003)
  between min_particles and max_particles;
- recovery: random particles in free space when the short-term average likelihood falls
  below the long-term one (recovery_alpha_slow/fast, Augmented MCL), and a global
  relocalisation that spreads max_particles over the whole free space on request, or by
  itself when the beams stop fitting the map (first a cloud along the path driven since
  the last scan that pinned the position).
"""
import math
from typing import NamedTuple, Optional, Tuple

import numpy as np

from turtlebot3c_common.message_fields import scan_range_limits
from turtlebot3c_common.parameter_files import like_default
from turtlebot3c_common.se2 import compose, cos_sin, relative, wrap_angle

from .grid_info import GridInfo
from .likelihood_field import LikelihoodField


class AmclParams(NamedTuple):
    min_particles: int = 500
    max_particles: int = 3000
    kld_err: float = 0.02
    kld_z: float = 0.99
    bin_size_xy: float = 0.5
    bin_size_yaw: float = math.radians(10.0)
    update_min_d: float = 0.20
    update_min_a: float = 0.20
    resample_interval: int = 1
    recovery_alpha_slow: float = 0.001
    recovery_alpha_fast: float = 0.1
    odom_alpha1: float = 0.1  # rotation noise from rotation
    odom_alpha2: float = 0.1  # rotation noise from translation
    odom_alpha3: float = 0.1  # translation noise from translation
    odom_alpha4: float = 0.1  # translation noise from rotation
    # m: below it the heading's noise fades from the rot1/rot2 split's to the net turn's
    # (see apply_motion); 0: the split's at every length, as amcl above 1 cm.
    odom_short_move: float = 0.1
    # At each update this share of the particles takes the step as a wheel slip would leave it:
    # anywhere from none of the distance the odometry read to odom_slip_max times it. The noise
    # above does not reach a slip (a 1.00 m step read as 0.34), and along a corridor whose walls
    # fit all along it no scan says the cloud fell behind (infinite-corridor, severe, odometry
    # seed 2: 4.3 m behind when the corridor ended, 0.614 m on average on the reference map;
    # 0.043 with this). Where the scans pin the position the slipped particles fit worse and go
    # at the next resampling. 0: none.
    odom_slip_share: float = 0.02
    odom_slip_max: float = 3.0
    laser_max_beams: int = 180
    laser_min_range: float = -1.0  # the scan's own range_min, or this where more
    laser_max_range: float = 3.5  # <= 0: use the scan's own range_max
    laser_z_hit: float = 0.5
    laser_z_rand: float = 0.5
    laser_sigma_hit: float = 0.2
    laser_likelihood_max_dist: float = 2.0
    # While the filter is converged, the beams that end short of the map's obstacles, in the
    # open, seen from the cloud's mean, are left out of the weighting, as they count neither way
    # in the lost check (below): something the map does not hold stands in front of its walls,
    # and scored against the map such beams pull the cloud to wherever they happen to end near a
    # wall. fhw, severe, odometry seed 3: in a turn among people (median range 0.8 m; at the
    # reference pose 16 of 180 beams end on the map's walls) one scan turned the cloud 84 degrees
    # off, and the filter was lost for 60 scans (2.19 m on average; 0.044 m with this).
    skip_short_beams: bool = True
    # m: only beams that end more than this short of the map's next obstacle along them are left
    # out. A beam that ends a little short is as likely the cloud's fault: after a wheel slip
    # the cloud lags, and the beams ahead end short of the wall they hit by the slip, yet they
    # alone say how far the robot went (acapulco, severe, seed 3, scan 829: a 0.99 m step read
    # as 0.32; with every short beam left out the cloud fell 1.5 m behind). 0.3, 0.5 and 0.7 m
    # were measured on every log and severity: each mends some rows of infinite-corridor and
    # breaks others, and 0.5 m loses one (docs/slam-real-data-history.md, session 36).
    short_beam_min_gap: float = 1.0
    # Beams are not independent: scaling the summed log-likelihood down keeps the filter
    # from collapsing onto one hypothesis after one scan (1.0 is the plain product of
    # beams). While the cloud is spread (several places, e.g. after a global
    # relocalisation in a symmetric world) the flatter scale keeps every hypothesis alive
    # until the robot sees what tells them apart; once it has one place, the sharper one
    # gives the accuracy.
    likelihood_scale: float = 1.0
    likelihood_scale_spread: float = 0.1
    converged_spread: float = 0.3  # m, position standard deviation of the main cluster
    converged_share: float = 0.9  # of the weight in the main cluster
    # Lost: when, for lost_updates filter updates in a row, fewer than lost_fit of the beams
    # that reach the map's obstacles, seen from the estimate, end on one (within
    # lost_fit_distance) rather than pass through it, the filter starts a global
    # relocalisation by itself (a wrong initial pose, a kidnapped robot). 0: never. A beam that
    # ends short, in the open, counts neither way: something the map does not hold stands in
    # front of its wall (people around the robot; fhw, in a turn on the spot, 80 % of the beams
    # at the reference pose), and that is no sign of being lost.
    lost_fit_distance: float = 0.2
    lost_fit: float = 0.8
    lost_updates: int = 8
    # While the filter is converged, a scan that carries the estimate more than this many of the
    # predicted cloud's standard deviations (position or heading) from its mean, to where fewer
    # than lost_fit of the beams end on the map's walls, is not weighted: the cloud goes on by
    # the odometry alone. Such a scan picked a pose in the tail of the motion noise on evidence
    # the map does not bear out. fhw, severe, odometry seed 2, in a turn among people: scan 59
    # fits the map of the even scans better turned 110 degrees than at the truth (20 and 7 of the
    # 180 beams end on a wall), a pose 2.7 heading deviations out, and the filter was lost for
    # the rest of the log (14.3 m on average; 0.048 with this). The other logs' poorly fitting
    # scans move the estimate at most 1.8 deviations, and still weigh. 0: every scan weighs.
    poor_fit_max_jump: float = 2.0
    # Before that global relocalisation, once per loss: a cloud along the odometry's path
    # since the last tracked estimate whose scan pinned the position (_follow_anchor), retraced
    # with the odometry's errors (odom_alpha1..3, see _respread_locally), with these standard
    # deviations (m, rad) around it. A slip or a turn the odometry misread leaves the cloud
    # behind or turned, near the robot; on a large map a global relocalisation finds it again
    # only hundreds of scans later. 0: straight to global.
    lost_local_std_xy: float = 1.0
    lost_local_std_yaw: float = 0.5
    initial_cov_xx: float = 0.5 * 0.5
    initial_cov_yy: float = 0.5 * 0.5
    initial_cov_aa: float = (math.pi / 12.0) ** 2


# A scan pins the position when, moved this far ahead, behind, left or right, fewer of its
# beams fit by at least PIN_MARGIN each way. Along a corridor the walls fit as well either way and
# the filter has only the odometry to say where along it the robot is: a slip there leaves the
# cloud behind while the beams still fit (infinite-corridor, severe, odometry seed 2: a 0.67 m
# slip, 3.6 m behind ten scans later), so such an estimate is no anchor for a re-spread.
PIN_SHIFT = 0.5  # m
PIN_MARGIN = 0.1  # share of the beams


# Parameters that divide or size the cloud, so must be more than 0. Every other number may be 0
# but not negative, except the laser's range limits (<= 0, as ROS amcl's -1: the scan's own).
POSITIVE_PARAMS = ("min_particles", "max_particles", "kld_err", "bin_size_xy", "bin_size_yaw", "laser_sigma_hit")
SIGNED_PARAMS = ("laser_min_range", "laser_max_range")


def params_from_dict(values) -> AmclParams:
    """AmclParams from a mapping (e.g. ROS parameters); ValueError with one line for an unknown
    key or a value the filter cannot run with."""
    unknown = set(values) - set(AmclParams._fields)
    if unknown:
        raise ValueError("unknown amcl parameters: {}; known: {}".format(
            ", ".join(sorted(unknown)), ", ".join(AmclParams._fields)))
    defaults = AmclParams()
    params = defaults._replace(**{name: _checked_param(name, value, getattr(defaults, name))
                                  for name, value in values.items()})
    if params.min_particles > params.max_particles:
        raise ValueError(f"amcl parameter min_particles ({params.min_particles}) must not be more than "
                         f"max_particles ({params.max_particles})")
    if not 0.0 < params.kld_z < 1.0:
        raise ValueError(f"amcl parameter kld_z must be a probability between 0 and 1, got {params.kld_z!r}")
    return params


def _checked_param(name, value, default):
    """`value` as the type of `default`, or ValueError saying what parameter `name` must be."""
    what = f"amcl parameter {name}"
    checked = like_default(value, default, what, positive=name in POSITIVE_PARAMS)
    if name not in SIGNED_PARAMS and checked < 0:
        raise ValueError(f"{what} must not be negative, got {value!r}")
    return checked


def checked_seed(value):
    """The filter's random seed: None (a new one each run) or a whole number numpy takes
    (0 to 2^32 - 1); ValueError with one line otherwise."""
    if value is None:
        return None
    seed = like_default(value, 0, "amcl parameter seed")
    if not 0 <= seed < 2 ** 32:
        raise ValueError(f"amcl parameter seed must be from 0 to 2^32 - 1, got {value!r}")
    return seed


def kld_particle_count(bins: int, error: float, z: float) -> float:
    """Particles needed so that the KL divergence to the true posterior stays below
    `error` with probability given by the normal quantile `z` (Fox 2003, eq. 15)."""
    if bins <= 1:
        return 1.0
    k = bins - 1
    a = 2.0 / (9.0 * k)
    return k / (2.0 * error) * (1.0 - a + math.sqrt(a) * z) ** 3


def _normal_quantile(p: float) -> float:
    """Inverse of the standard normal CDF (Acklam's rational approximation, |error| < 1e-8)."""
    a = (-3.969683028665376e01, 2.209460984245205e02, -2.759285104469687e02,
         1.383577518672690e02, -3.066479806614716e01, 2.506628277459239e00)
    b = (-5.447609879822406e01, 1.615858368580409e02, -1.556989798598866e02,
         6.680131188771972e01, -1.328068155288572e01)
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e00,
         -2.549732539343734e00, 4.374664141464968e00, 2.938163982698783e00)
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e00, 3.754408661907416e00)
    if p < 0.02425:
        q = math.sqrt(-2.0 * math.log(p))
        return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) / \
            ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0)
    if p > 1.0 - 0.02425:
        return -_normal_quantile(1.0 - p)
    q = p - 0.5
    r = q * q
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q / \
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0)


class Estimate(NamedTuple):
    pose: Tuple[float, float, float]
    covariance: np.ndarray  # 3 x 3 over (x, y, yaw)
    share: float = 1.0  # of the particle weight in the cluster the pose comes from


class ParticleFilter:
    def __init__(self, occupied, info: GridInfo, free=None, params: Optional[AmclParams] = None, seed=None):
        """`occupied` and `free` are bool grids over `info` (free defaults to not occupied)."""
        params = params or AmclParams()
        self.params = params
        self.info = info
        self.rng = np.random.RandomState(seed)
        self.field = LikelihoodField(
            occupied, info, max_distance=params.laser_likelihood_max_dist, sigma_hit=params.laser_sigma_hit,
            z_hit=params.laser_z_hit, z_rand=params.laser_z_rand,
            max_range=self.beam_limits(0.0, math.inf)[1])  # until a scan gives its own range_max
        free = ~np.asarray(occupied, dtype=bool) if free is None else np.asarray(free, dtype=bool)
        rows, cols = np.nonzero(free)
        if rows.size == 0:
            raise ValueError("the map has no free cell to localise in")
        self._free_x, self._free_y = info.cell_to_world(rows, cols)
        self._kld_z = _normal_quantile(params.kld_z)
        self.particles = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self.last_odom: Optional[Tuple[float, float, float]] = None
        self._force_update = False
        self._updates = 0
        self._w_slow = 0.0
        self._w_fast = 0.0
        self.estimate: Optional[Estimate] = None
        self.fit = 1.0  # share of the beams reaching the map's obstacles that end on one, from the estimate
        self._lost_count = 0
        self.relocalizations = 0  # global relocalisations started because the robot was lost
        self.local_respreads = 0  # clouds spread along the path driven because the robot was lost
        self.unweighted_scans = 0  # scans that jumped the estimate to a poor fit (poor_fit_max_jump)
        self._local_tried = False  # since the beams last fitted
        self._anchor = None  # (estimate, [odometry at each update since]) when a scan last pinned the position
        self._candidate = None  # the same, while the fit it came in has not yet held (_follow_anchor)
        self._fit_streak = 0
        self._tracked = False  # the beams fitted lost_updates updates in a row since the last pose given

    @property
    def initialized(self) -> bool:
        return self.particles.shape[0] > 0

    # --- initialisation ---------------------------------------------------------------

    def set_pose(self, pose, covariance=None):
        """Gaussian cloud of max_particles around `pose` (e.g. RViz's 2D Pose Estimate)."""
        p = self.params
        cov = np.diag([p.initial_cov_xx, p.initial_cov_yy, p.initial_cov_aa]) if covariance is None \
            else np.asarray(covariance, dtype=float)
        count = p.max_particles
        samples = self.rng.multivariate_normal(np.zeros(3), cov, size=count)
        samples += np.asarray(pose, dtype=float)
        self._set_cloud(samples, pose, cov)

    def _set_cloud(self, samples, pose, covariance):
        samples[:, 2] = wrap_angle(samples[:, 2])
        self._reset(samples)
        self._local_tried = False
        self._anchor = self._candidate = None
        self._fit_streak = 0
        self._tracked = False
        self.estimate = Estimate(tuple(float(v) for v in pose), covariance, 1.0)

    def global_localization(self):
        """Spread max_particles uniformly over free space with uniform headings."""
        count = self.params.max_particles
        chosen = self.rng.randint(0, self._free_x.size, size=count)
        self._reset(self._random_free_poses(chosen))
        self._tracked = False
        self.estimate = None

    def _random_free_poses(self, chosen):
        res = self.info.resolution
        x = self._free_x[chosen] + self.rng.uniform(-res / 2, res / 2, chosen.size)
        y = self._free_y[chosen] + self.rng.uniform(-res / 2, res / 2, chosen.size)
        yaw = self.rng.uniform(-math.pi, math.pi, chosen.size)
        return np.column_stack([x, y, yaw])

    def _reset(self, particles):
        self._lost_count = 0
        self.particles = particles
        self.weights = np.full(particles.shape[0], 1.0 / particles.shape[0])
        self._force_update = True
        self._w_slow = self._w_fast = 0.0

    # --- the filter -------------------------------------------------------------------

    def moved_enough(self, odom) -> bool:
        if self.last_odom is None:
            return False
        dx, dy = odom[0] - self.last_odom[0], odom[1] - self.last_odom[1]
        return (math.hypot(dx, dy) >= self.params.update_min_d
                or abs(wrap_angle(odom[2] - self.last_odom[2])) >= self.params.update_min_a)

    def update(self, odom, ranges, angles, range_min=0.0, sensor_offset=(0.0, 0.0, 0.0), range_max=math.inf) -> bool:
        """Feed one scan (its beams, their angles and the scan's range_min and range_max) and the
        odometry pose at its time. Returns True when the filter ran (moved enough since the last
        run, or a new initial pose / relocalisation is pending)."""
        if not self.initialized:
            return False
        if self.last_odom is None:
            self.last_odom = tuple(odom)
            self._force_update = True
        if not (self._force_update or self.moved_enough(odom)):
            return False
        self.apply_motion(self.last_odom, odom)
        self.last_odom = tuple(odom)
        self._force_update = False
        self.apply_scan(ranges, angles, range_min, sensor_offset, range_max)
        self._updates += 1
        if self._updates % max(1, self.params.resample_interval) == 0:
            self.resample()
        if self._lost(ranges, angles, range_min, sensor_offset, range_max):
            if self._tracked and self._anchor and not self._local_tried and self.params.lost_local_std_xy > 0.0:
                self._respread_locally(odom)
            else:
                self.global_localization()
                self.relocalizations += 1
        return True

    def _lost(self, ranges, angles, range_min, sensor_offset, range_max) -> bool:
        p = self.params
        if p.lost_updates <= 0 or self.estimate is None:
            return False
        ranges, angles = self.select_beams(ranges, angles, range_min, range_max)
        if ranges.size == 0:
            return False
        ends_on, passes_through = self._classify_beams(self.estimate.pose, ranges, angles, sensor_offset)
        fit = _fit_share(ends_on, passes_through)
        if fit is not None:
            self.fit = fit
            self._lost_count = self._lost_count + 1 if fit < p.lost_fit else 0
        if self._lost_count == 0:
            self._local_tried = False
        # Only a filter that tracked (the beams fitted lost_updates updates in a row since the
        # pose was last given or spread globally) is spread locally when lost: one given a wrong
        # pose fits now and then by chance, and a cloud around it can settle on a look-alike
        # nearby that the lost check then accepts (the house, from 1.8 m and 2 rad off).
        self._fit_streak = self._fit_streak + 1 if self._lost_count == 0 else 0
        self._tracked = self._tracked or self._fit_streak >= p.lost_updates
        pins = self._lost_count == 0 and self._pins_position(ranges, angles, sensor_offset, float(ends_on.mean()))
        self._follow_anchor(pins)
        return self._lost_count >= p.lost_updates

    def _follow_anchor(self, pins):
        """Extend the paths since the anchor and its candidate by this update's odometry. A scan
        that pins the position makes its estimate the candidate; the candidate becomes the anchor
        once the fit it came in has held lost_updates updates in a row, and is dropped if the fit
        breaks before. As a wrong pose given fits now and then (see _lost), so does a cloud that
        a scan turned onto a wrong heading: fhw, severe, odometry seed 1, filter seed 110, in the
        turn among people, scan 61 fitted 86 degrees off between two scans that did not, and the
        cloud spread around it when the filter took itself for lost never found the robot again."""
        odom = tuple(self.last_odom)
        for held in (self._anchor, self._candidate):
            if held is not None:
                held[1].append(odom)
        if self._lost_count:
            self._candidate = None
        elif pins:
            self._candidate = (self.estimate.pose, [odom])
        if self._candidate is not None and self._fit_streak >= self.params.lost_updates:
            self._anchor, self._candidate = self._candidate, None

    def _classify_beams(self, pose, ranges, angles, sensor_offset):
        """Which beams, seen from `pose`, end on an obstacle (within lost_fit_distance) and which
        pass through one; the others end short, in the open. Two bool arrays."""
        margin = self.params.lost_fit_distance
        ends_on = self.field.end_point_distances(pose, ranges, angles, sensor_offset) < margin
        passes_through = np.zeros(ends_on.shape, dtype=bool)
        passes_through[~ends_on] = self.field.passes_obstacle(
            pose, ranges[~ends_on], angles[~ends_on], margin, sensor_offset)
        return ends_on, passes_through

    def _beams_near_obstacles(self, pose, ranges, angles, sensor_offset):
        """Which beams, seen from `pose`, end on an obstacle, pass through one, or end at most
        short_beam_min_gap short of the next one along them; the others end far out in the open.
        One march per beam: a beam that passes through an obstacle also meets one within its
        range plus the gap."""
        near = self.field.end_point_distances(pose, ranges, angles, sensor_offset) < self.params.lost_fit_distance
        off = np.nonzero(~near)[0]
        near[off] = self.field.passes_obstacle(
            pose, ranges[off] + self.params.short_beam_min_gap, angles[off], 0.0, sensor_offset)
        return near

    def _pins_position(self, ranges, angles, sensor_offset, fit_here) -> bool:
        """Whether the scan fits clearly worse PIN_SHIFT ahead of, behind, left and right of the
        estimate, where fit_here of its beams end on an obstacle."""
        p = self.params
        x, y, yaw = self.estimate.pose
        for direction in (yaw, yaw + math.pi, yaw + math.pi / 2, yaw - math.pi / 2):
            moved = (x + PIN_SHIFT * math.cos(direction), y + PIN_SHIFT * math.sin(direction), yaw)
            distances = self.field.end_point_distances(moved, ranges, angles, sensor_offset)
            if float((distances < p.lost_fit_distance).mean()) > fit_here - PIN_MARGIN:
                return False
        return True

    def _respread_locally(self, odom):
        """A cloud along the odometry's path since the anchor, each particle retracing it with
        errors of its own, a distance scale (odom_alpha3) and a turn scale (odom_alpha1), as a
        wheel's scale error or slip and a misread turn stretch and bend the path; then
        lost_local_std_xy/yaw around it."""
        p = self.params
        pose, path = self._anchor
        count = p.max_particles
        normal = self.rng.normal
        distance_scale = 1.0 + normal(0.0, math.sqrt(p.odom_alpha3), count)
        turn_scale = 1.0 + normal(0.0, math.sqrt(p.odom_alpha1), count)
        x, y, yaw = (np.full(count, value) for value in pose)
        for start, end in zip(path, path[1:]):
            dx, dy, turn = relative(start, end)
            cos, sin = np.cos(yaw), np.sin(yaw)
            x += distance_scale * (cos * dx - sin * dy)
            y += distance_scale * (sin * dx + cos * dy)
            yaw += turn_scale * turn
        spread = (p.lost_local_std_xy, p.lost_local_std_xy, p.lost_local_std_yaw)
        samples = np.column_stack([x, y, yaw]) + normal(0.0, 1.0, (count, 3)) * spread
        self._set_cloud(samples, compose(pose, relative(path[0], tuple(odom))), np.cov(samples.T))
        self._anchor, self._tracked, self._local_tried = (pose, path), True, True
        self.local_respreads += 1

    def apply_motion(self, odom_from, odom_to):
        """Move every particle by the odometry increment, with sampled noise.

        The increment is read as amcl's rot1, trans, rot2, each with its noise; the heading
        takes the noise of both turns. For a move shorter than odom_short_move that split
        means less and less: turning in place about a point a few centimetres off the base
        frame moves the frame sideways, and rot1, trans, rot2 read that as a quarter turn, the
        move and a quarter turn back (a 0.5 rad turn with a 5 cm sideways move spread the
        heading by 0.6 rad at alpha1 0.1, against 0.16 for the turn alone; on a large map a
        pose a quarter turn off then fitted the scan better than the truth). So below
        odom_short_move the heading's noise fades, with the square of the move's length, from
        the split's to the net turn's (amcl's pure rotation below 1 cm, made gradual); the
        direction of the move keeps rot1's noise. A turn in place keeps alpha1 * turn^2."""
        p = self.params
        dx, dy = odom_to[0] - odom_from[0], odom_to[1] - odom_from[1]
        trans = math.hypot(dx, dy)
        turn = wrap_angle(odom_to[2] - odom_from[2])
        rot1 = 0.0 if trans < 0.01 else wrap_angle(math.atan2(dy, dx) - odom_from[2])
        rot2 = wrap_angle(turn - rot1)
        # Driving backwards is not a half turn: noise follows the smaller angle.
        rot1_noise = min(abs(rot1), abs(wrap_angle(rot1 - math.pi)))
        rot2_noise = min(abs(rot2), abs(wrap_angle(rot2 - math.pi)))
        n = self.particles.shape[0]
        normal = self.rng.normal
        rot1_error = normal(0.0, math.sqrt(p.odom_alpha1 * rot1_noise ** 2 + p.odom_alpha2 * trans ** 2), n)
        trans_hat = trans - normal(
            0.0, math.sqrt(p.odom_alpha3 * trans ** 2 + p.odom_alpha4 * (rot1_noise ** 2 + rot2_noise ** 2)), n)
        rot2_error = normal(0.0, math.sqrt(p.odom_alpha1 * rot2_noise ** 2 + p.odom_alpha2 * trans ** 2), n)
        trans_hat = self._with_slips(trans, trans_hat)
        yaw = self.particles[:, 2]
        heading = yaw + (rot1 - rot1_error)
        self.particles[:, 0] += trans_hat * np.cos(heading)
        self.particles[:, 1] += trans_hat * np.sin(heading)
        split = self._split_weight(trans)
        if split >= 1.0:
            self.particles[:, 2] = wrap_angle(heading + (rot2 - rot2_error))
            return
        turn_error = normal(0.0, math.sqrt(p.odom_alpha1 * turn ** 2 + p.odom_alpha2 * trans ** 2), n)
        heading_error = split * (rot1_error + rot2_error) + math.sqrt(1.0 - split * split) * turn_error
        self.particles[:, 2] = wrap_angle(yaw + turn - heading_error)

    def _with_slips(self, trans, trans_hat):
        """The particles' distances, odom_slip_share of them drawn as a slip's instead."""
        p = self.params
        if p.odom_slip_share <= 0.0:
            return trans_hat
        n = trans_hat.size
        slipped = self.rng.uniform(size=n) < p.odom_slip_share
        return np.where(slipped, trans * self.rng.uniform(0.0, p.odom_slip_max, n), trans_hat)

    def _split_weight(self, trans) -> float:
        """How much of the rot1/rot2 split's heading noise a move of `trans` m keeps (1: all)."""
        short = self.params.odom_short_move
        if short <= 0.0 or trans >= short:
            return 1.0
        return (trans / short) ** 2

    def beam_limits(self, range_min, range_max) -> Tuple[float, float]:
        """The ranges (m) a beam must lie between to weigh, for a scan that declares these limits,
        as in ROS amcl: from its range_min, or laser_min_range where more, to its range_max, or
        laser_max_range where less (<= 0: the scan's)."""
        low, high = scan_range_limits(range_min, range_max)
        p = self.params
        return max(p.laser_min_range, low), (min(p.laser_max_range, high) if p.laser_max_range > 0 else high)

    def select_beams(self, ranges, angles, range_min, range_max=math.inf):
        """Valid beams (finite range and angle, within limits), evenly thinned to laser_max_beams."""
        p = self.params
        ranges = np.asarray(ranges, dtype=float)
        angles = np.asarray(angles, dtype=float)
        low, high = self.beam_limits(range_min, range_max)
        valid = np.isfinite(ranges) & np.isfinite(angles) & (ranges > low) & (ranges < high)
        ranges, angles = ranges[valid], angles[valid]
        if ranges.size > p.laser_max_beams > 0:
            pick = np.linspace(0, ranges.size - 1, p.laser_max_beams).round().astype(int)
            ranges, angles = ranges[pick], angles[pick]
        return ranges, angles

    def apply_scan(self, ranges, angles, range_min=0.0, sensor_offset=(0.0, 0.0, 0.0), range_max=math.inf):
        """Weight particles by the scan; update the estimate and the recovery averages."""
        reach = self.beam_limits(range_min, range_max)[1]
        if reach < math.inf:
            self.field.use_max_range(reach)
        selected = self.select_beams(ranges, angles, range_min, range_max)
        ranges, angles = selected
        if ranges.size == 0:
            # No beam weighs the cloud, but the motion before moved it: the estimate follows it.
            # Left as it was, the pose published stayed where the robot had been for as long as
            # its LIDAR saw nothing (a recording's empty scans put it 1 and 2 m behind).
            self.estimate = self._estimate()
            return
        converged = self.converged()
        prior_weights, prior_mean = self.weights, _weighted_pose_mean(self.particles, self.weights)
        if converged and self.params.skip_short_beams:
            kept = self._beams_near_obstacles(prior_mean, ranges, angles, sensor_offset)
            if kept.any():  # else the scan is all short: it weighs as a whole, as before
                ranges, angles = ranges[kept], angles[kept]
        scale = self.params.likelihood_scale if converged else self.params.likelihood_scale_spread
        log_likelihood = self.field.log_likelihood(self.particles, ranges, angles, sensor_offset)
        log_prior = np.log(np.maximum(self.weights, 1e-300))
        log_w = log_likelihood * scale + log_prior
        peak = log_w.max()
        weights = np.exp(log_w - peak)
        self.weights = weights / weights.sum()
        # Average per-beam likelihood of the cloud, the quantity Augmented MCL tracks: of the
        # sensor model itself, not of the scaled weights, so that it means the same whether
        # the cloud was spread (likelihood_scale_spread) or not when w_slow and w_fast saw it.
        expected = log_likelihood + log_prior
        top = expected.max()
        mean_likelihood = math.exp((top + math.log(np.exp(expected - top).sum())) / ranges.size)
        self._track_likelihood(mean_likelihood)
        self.estimate = self._estimate()
        if converged and self._jumped_to_a_poor_fit(prior_weights, prior_mean, *selected, sensor_offset):
            self.weights = prior_weights
            self.estimate = self._estimate()
            self.unweighted_scans += 1

    def _jumped_to_a_poor_fit(self, prior_weights, prior_mean, ranges, angles, sensor_offset) -> bool:
        """Whether the estimate moved more than poor_fit_max_jump of the predicted cloud's
        standard deviations (the particles under `prior_weights`) from its mean, to where the scan
        fits poorly (see AmclParams)."""
        limit = self.params.poor_fit_max_jump
        if limit <= 0.0:
            return False
        x, y, yaw = self.estimate.pose
        position_std, heading_std = _weighted_pose_spread(self.particles, prior_weights, prior_mean)
        jump = max(math.hypot(x - prior_mean[0], y - prior_mean[1]) / max(position_std, 1e-9),
                   abs(wrap_angle(yaw - prior_mean[2])) / max(heading_std, 1e-9))
        if jump <= limit:
            return False
        fit = _fit_share(*self._classify_beams(self.estimate.pose, ranges, angles, sensor_offset))
        return fit is not None and fit < self.params.lost_fit

    def _track_likelihood(self, mean_likelihood):
        p = self.params
        if p.recovery_alpha_slow <= 0 or p.recovery_alpha_fast <= 0:
            return
        if self._w_slow == 0.0:
            self._w_slow = self._w_fast = mean_likelihood
        else:
            self._w_slow += p.recovery_alpha_slow * (mean_likelihood - self._w_slow)
            self._w_fast += p.recovery_alpha_fast * (mean_likelihood - self._w_fast)

    def _bins(self, particles):
        p = self.params
        keys = np.column_stack([
            np.floor(particles[:, 0] / p.bin_size_xy), np.floor(particles[:, 1] / p.bin_size_xy),
            np.floor(particles[:, 2] / p.bin_size_yaw)]).astype(np.int64)
        # One integer per bin (coordinates stay far below 2^20 bins per axis).
        return (keys[:, 0] + (1 << 20)) * (1 << 42) + (keys[:, 1] + (1 << 20)) * (1 << 21) + keys[:, 2] + (1 << 20)

    def resample(self):
        """Low-variance resampling; KLD decides how many particles to keep."""
        p = self.params
        weights = self.weights
        cumulative = np.cumsum(weights)
        cumulative[-1] = 1.0
        draws = p.max_particles
        positions = (self.rng.uniform() + np.arange(draws)) / draws
        picked = np.searchsorted(cumulative, positions)
        picked = picked[self.rng.permutation(draws)]
        candidates = self.particles[picked]
        count = self._kld_count(candidates)
        new_particles = candidates[:count].copy()
        inject = self._random_particle_share()
        if inject > 0.0:
            replace = self.rng.uniform(size=count) < inject
            if replace.any():
                chosen = self.rng.randint(0, self._free_x.size, size=int(replace.sum()))
                new_particles[replace] = self._random_free_poses(chosen)
        self.particles = new_particles
        self.weights = np.full(count, 1.0 / count)

    def _kld_count(self, candidates) -> int:
        p = self.params
        bins = self._bins(candidates)
        _, first = np.unique(bins, return_index=True)
        is_new = np.zeros(bins.size, dtype=np.int64)
        is_new[first] = 1
        distinct = np.cumsum(is_new)  # distinct bins among the first n+1 candidates
        k = np.maximum(distinct - 1, 1).astype(float)
        a = 2.0 / (9.0 * k)
        needed = np.where(distinct > 1, k / (2.0 * p.kld_err) * (1.0 - a + np.sqrt(a) * self._kld_z) ** 3, 1.0)
        counts = np.arange(1, bins.size + 1)
        enough = (counts >= needed) & (counts >= p.min_particles)
        hits = np.nonzero(enough)[0]
        return int(hits[0] + 1) if hits.size else int(bins.size)

    def _random_particle_share(self) -> float:
        if self._w_slow <= 0.0:
            return 0.0
        return max(0.0, 1.0 - self._w_fast / self._w_slow)

    def _estimate(self) -> Estimate:
        """Weighted mean and covariance of the heaviest cluster (particles near the
        heaviest KLD bin), so a multi-modal cloud does not average two places."""
        bins = self._bins(self.particles)
        unique, inverse = np.unique(bins, return_inverse=True)
        mass = np.bincount(inverse, weights=self.weights)
        best = self.particles[inverse == np.argmax(mass)]
        best_w = self.weights[inverse == np.argmax(mass)]
        centre = _weighted_pose_mean(best, best_w)
        near = ((np.hypot(self.particles[:, 0] - centre[0], self.particles[:, 1] - centre[1]) < 1.0)
                & (np.abs(wrap_angle(self.particles[:, 2] - centre[2])) < 0.5))
        cluster, cluster_w = self.particles[near], self.weights[near]
        mean = _weighted_pose_mean(cluster, cluster_w)
        diff = cluster - np.asarray(mean)
        diff[:, 2] = wrap_angle(diff[:, 2])
        w = cluster_w / cluster_w.sum()
        covariance = (diff * w[:, None]).T @ diff
        return Estimate(mean, covariance, float(cluster_w.sum() / self.weights.sum()))

    def converged(self) -> bool:
        """One place holds nearly all the weight, and it is tight."""
        estimate = self.estimate
        if estimate is None:
            return False
        spread = math.sqrt(max(0.0, estimate.covariance[0, 0] + estimate.covariance[1, 1]))
        return estimate.share >= self.params.converged_share and spread <= self.params.converged_spread

    def spread(self) -> Tuple[float, float]:
        """Position (m) and heading (rad) standard deviations of the whole cloud."""
        return _weighted_pose_spread(self.particles, self.weights, _weighted_pose_mean(self.particles, self.weights))


def _fit_share(ends_on, passes_through) -> Optional[float]:
    """Of the beams that reach the map's obstacles, the share that end on one; None when every
    beam ends short, in the open: no evidence either way."""
    reaching = int(ends_on.sum() + passes_through.sum())
    return float(ends_on.sum()) / reaching if reaching else None


def _weighted_pose_spread(poses, weights, mean) -> Tuple[float, float]:
    """Position (m) and heading (rad) standard deviations of `poses` (weights summing to 1)
    about `mean`."""
    diff = poses - np.asarray(mean)
    diff[:, 2] = wrap_angle(diff[:, 2])
    var = (diff ** 2 * weights[:, None]).sum(axis=0)
    return math.sqrt(var[0] + var[1]), math.sqrt(var[2])


def _weighted_pose_mean(poses, weights) -> Tuple[float, float, float]:
    w = weights / weights.sum()
    x = float((poses[:, 0] * w).sum())
    y = float((poses[:, 1] * w).sum())
    cos, sin = cos_sin(poses[:, 2])
    yaw = math.atan2(float((sin * w).sum()), float((cos * w).sum()))
    return (x, y, yaw)
