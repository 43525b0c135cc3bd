"""The SLAM core: geometry, grids, matching, pose graph, and whole runs in the simulator against ground truth."""
import copy
import math

import numpy as np
import pytest
import yaml

from testkit.real_data import SHIPPED_SLAM_CONFIG
from turtlebot3c_common.se2 import compose, interpolate_pose, inverse, relative, transform_points, wrap_angle
from turtlebot3c_sim.evaluation import (
    ROUTES,
    absolute_trajectory_error,
    cell_agreement,
    drive_route,
    occupied_precision,
)
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world, world_from_description
from turtlebot3c_slam.line_icp import LineCloud, align
from turtlebot3c_slam.loop_closure import (
    DriftPath,
    LoopCloser,
    LoopClosure,
    keyframes_agree,
    nearest_view,
    within_check,
)
from turtlebot3c_slam.occupancy_grid import CellUpdate, LogOddsGrid, trace_scan
from turtlebot3c_slam.pose_graph import PoseGraph, diagonal_information
from turtlebot3c_slam.scan_matcher import GridMatcher, _block_maxima, sparse_likelihood_field
from turtlebot3c_slam.slam import (
    Keyframe,
    RedrawBudget,
    Slam,
    SlamConfig,
    check_slam_method,
    positions_towards,
)
from turtlebot3c_slam.slam_messages import mount_from_transform
from turtlebot3c_slam.slam_scan import ScanGeometry, ScanRays, scan_rays

# --- plane geometry and scans ----------------------------------------------------------------


def test_compose_inverse_and_between_agree():
    a, b = (1.0, -2.0, 0.7), (0.3, 0.4, -2.9)
    assert compose(a, inverse(a)) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert compose(a, relative(a, b)) == pytest.approx(b)
    assert transform_points(a, [[0.3, 0.4]])[0] == pytest.approx(compose(a, b)[:2])


def test_ranges_are_read_as_hits_free_rays_or_nothing_for_any_geometry():
    # 180 beams over 180 degrees, a long-range LIDAR mounted backwards at x = 0.1.
    geometry = ScanGeometry(-math.pi / 2, math.pi / 179, 180, 0.1, 80.0, mount=(0.1, 0.0, math.pi))
    ranges = np.full(180, np.nan)
    ranges[0] = 2.0        # hit
    ranges[1] = np.inf     # nothing in reach: free up to the usable range
    ranges[2] = 0.0        # driver's "no measurement"
    ranges[3] = 0.05       # below range_min
    ranges[4] = 80.0       # at range_max: no return
    ranges[5] = 50.0       # a hit beyond the usable range: free up to it, not a wall
    ranges[6] = -np.inf
    rays = scan_rays(geometry, ranges, usable_range=8.0)
    assert len(rays.hits) == 1
    # Beam 0 points at -90 degrees in the scan frame, +90 degrees on the backwards mount.
    assert rays.hits[0] == pytest.approx([0.1, 2.0], abs=1e-9)
    assert len(rays.free_ends) == 3
    assert np.hypot(*(rays.free_ends - [0.1, 0.0]).T) == pytest.approx([8.0, 8.0, 8.0])


def test_upside_down_mount_turns_beams_clockwise():
    geometry = ScanGeometry(0.0, math.pi / 2, 4, 0.1, 10.0, upside_down=True)
    rays = scan_rays(geometry, [1.0, 2.0, np.nan, np.nan], usable_range=10.0)
    assert rays.hits == pytest.approx(np.array([[1.0, 0.0], [0.0, -2.0]]), abs=1e-12)


def test_a_zero_reading_is_no_measurement_even_when_the_scan_declares_no_range_min():
    geometry = ScanGeometry(0.0, math.pi / 2, 4, 0.0, 10.0)
    rays = scan_rays(geometry, [0.0, 2.0, 10.0, np.nan], usable_range=8.0)
    assert rays.hits == pytest.approx(np.array([[0.0, 2.0]]), abs=1e-12)
    assert rays.free_ends == pytest.approx(np.array([[-8.0, 0.0]]), abs=1e-12)


def test_scan_with_wrong_number_of_ranges_is_rejected():
    geometry = ScanGeometry(0.0, 0.1, 10, 0.1, 10.0)
    with pytest.raises(ValueError, match="3 ranges, its geometry 10"):
        scan_rays(geometry, [1.0, 2.0, 3.0], 8.0)


class _Vector:
    def __init__(self, x=0.0, y=0.0, z=0.0, w=1.0):
        self.x, self.y, self.z, self.w = x, y, z, w


class _Transform:
    def __init__(self, translation, rotation):
        self.translation, self.rotation = _Vector(*translation), _Vector(*rotation)


def test_lidar_mount_from_tf_knows_yaw_and_upside_down():
    half = math.sqrt(0.5)
    turned = mount_from_transform(_Transform((0.1, 0.02, 0.2), (0.0, 0.0, half, half)))  # yaw +90 degrees
    assert turned == pytest.approx((0.1, 0.02, math.pi / 2, False))
    flipped = mount_from_transform(_Transform((0.0, 0.0, 0.2), (1.0, 0.0, 0.0, 0.0)))  # roll 180 degrees
    assert flipped[2] == pytest.approx(0.0) and flipped[3] is True


def test_odometry_between_messages_is_interpolated_the_short_way_round():
    before, after = (0.0, 0.0, math.pi - 0.1), (1.0, 2.0, -math.pi + 0.1)
    x, y, yaw = interpolate_pose(before, after, 0.25)
    assert (x, y) == pytest.approx((0.25, 0.5))
    assert math.cos(yaw) == pytest.approx(math.cos(math.pi - 0.05))
    assert math.sin(yaw) == pytest.approx(math.sin(math.pi - 0.05))


# --- grids ------------------------------------------------------------------------------------


def wall_scan():
    """A 180-beam scan from the origin of a wall at x = 1 (y in -1..1), as rays."""
    geometry = ScanGeometry(-math.pi / 4, math.pi / 2 / 179, 180, 0.1, 10.0)
    angles = -math.pi / 4 + np.arange(180) * math.pi / 2 / 179
    return scan_rays(geometry, 1.0 / np.cos(angles), usable_range=8.0)


def test_scan_marks_hit_cells_occupied_and_cells_before_them_free():
    grid = LogOddsGrid(0.05)
    grid.apply(trace_scan(wall_scan(), (0.0, 0.0, 0.0), 0.05))
    occupancy = grid.to_occupancy_map()
    assert cell_state(occupancy, 1.01, 0.0) == 100
    assert cell_state(occupancy, 0.5, 0.0) == 0
    assert cell_state(occupancy, 0.5, 0.2) == 0
    assert cell_state(occupancy, 1.2, 0.0) == -1  # behind the wall: never seen
    assert cell_state(occupancy, -0.5, 0.0) == -1  # outside the field of view


def test_a_wall_hit_by_some_rays_and_passed_by_others_stays_occupied_until_misses_outweigh_its_hits():
    """A wall seen at a grazing angle or from afar is hit by some of the rays that reach it and
    passed by others. AMCL sees occupied cells only: a map that called such a wall unknown lost
    it (aces, a map of the even scans: a corridor's walls, AMCL 1.9 m off). People walking by
    still clear: a cell passed by enough rays goes free."""
    grid = LogOddsGrid(0.05)
    grid.add_scan(wall_scan(), (0.0, 0.0, 0.0))
    wall_cell = np.array([[20, 0]])  # x 1.00-1.05, y 0.00-0.05: hit by the scan
    passed = CellUpdate(free=wall_cell, hits=np.zeros((0, 2), dtype=np.int64))
    for _ in range(2):  # two misses weigh less than one hit (0.4 each against 0.85)
        grid.apply(passed)
        assert cell_state(grid.to_occupancy_map(), 1.01, 0.01) == 100
    grid.apply(passed)
    assert cell_state(grid.to_occupancy_map(), 1.01, 0.01) == 0


def test_a_ray_with_no_return_never_clears_a_wall_nor_what_lies_behind_it():
    """Glass, a black wall, a missed echo: a no-return says nothing past a wall other scans saw."""
    grid = LogOddsGrid(0.05)
    grid.add_scan(wall_scan(), (0.0, 0.0, 0.0))
    blind = scan_rays(wall_scan().geometry, np.full(180, np.inf), usable_range=8.0)
    for _ in range(5):
        grid.add_scan(blind, (0.0, 0.0, 0.0))
    occupancy = grid.to_occupancy_map()
    assert cell_state(occupancy, 1.01, 0.0) == 100
    assert cell_state(occupancy, 0.5, 0.0) == 0
    assert cell_state(occupancy, 1.5, 0.0) == -1 and cell_state(occupancy, 3.0, 0.3) == -1
    # Traced without the grid's walls (as before), the same rays wipe the wall out.
    unguarded = LogOddsGrid(0.05)
    unguarded.add_scan(wall_scan(), (0.0, 0.0, 0.0))
    for _ in range(5):
        unguarded.apply(trace_scan(blind, (0.0, 0.0, 0.0), 0.05))
    assert cell_state(unguarded.to_occupancy_map(), 1.01, 0.0) == 0


def test_the_shipped_config_states_every_parameter_at_the_code_defaults():
    """The node loads config/slam.yaml; the unit tests run SlamConfig(): they must be one SLAM."""
    shipped = yaml.safe_load(SHIPPED_SLAM_CONFIG.read_text())
    assert shipped == dict(SlamConfig().as_dict())


def test_slam_keeps_a_wall_that_later_scans_see_no_echo_from():
    slam = Slam()
    geometry = ScanGeometry(-math.pi / 4, math.pi / 2 / 179, 180, 0.1, 10.0)
    angles = -math.pi / 4 + np.arange(180) * math.pi / 2 / 179
    slam.add_scan(0.0, 1.0 / np.cos(angles), geometry, (0.0, 0.0, 0.0))
    turn = 1.5 * slam.config.keyframe_angle
    for step in range(1, 6):  # turning on the spot, a keyframe each time, the wall now unseen
        slam.add_scan(float(step), np.full(180, np.inf), geometry, (0.0, 0.0, 0.05 * step * (-1) ** step))
        slam.add_scan(step + 0.5, np.full(180, np.inf), geometry, (0.0, 0.0, turn * (-1) ** step))
    assert len(slam.keyframes) > 3
    occupancy = slam.occupancy_map()
    assert cell_state(occupancy, 1.0, 0.0) == 100 and cell_state(occupancy, 1.0, 0.5) == 100
    assert cell_state(occupancy, 2.0, 0.0) == -1


def room_ranges(pose, angles, half_width=2.0):
    """Ranges from `pose` to the walls of a square room centred on the origin."""
    directions = pose[2] + angles
    dx, dy = np.cos(directions), np.sin(directions)
    with np.errstate(divide="ignore"):
        to_x = np.where(dx > 0, half_width - pose[0], -half_width - pose[0]) / dx
        to_y = np.where(dy > 0, half_width - pose[1], -half_width - pose[1]) / dy
    return np.minimum(np.abs(to_x), np.abs(to_y))


def slam_tracking_in_a_room():
    """A SLAM that has tracked three scans 0.3 m apart along a square room's x axis, odometry
    exact; with the 360-beam geometry and beam angles it took them with."""
    geometry = ScanGeometry(-math.pi, 2 * math.pi / 360, 360, 0.1, 10.0)
    angles = -math.pi + np.arange(360) * 2 * math.pi / 360
    slam = Slam()
    for step in range(3):
        pose = (0.3 * step - 0.6, 0.0, 0.0)
        slam.add_scan(float(step), room_ranges(pose, angles), geometry, pose)
    return slam, geometry, angles


def test_a_scan_that_matches_poorly_never_becomes_a_keyframe_unless_poor_ones_go_on():
    """Its pose is odometry's guess; drawn into the local map it would mislead the next scans."""
    slam, geometry, angles = slam_tracking_in_a_room()
    keyframes = len(slam.keyframes)
    garbage = np.random.RandomState(2).uniform(0.3, 6.0, 360)  # what a dirty or blinded LIDAR gives
    slam.add_scan(3.0, garbage, geometry, (0.3, 0.0, 0.0))
    assert slam.poor_matches == 1 and len(slam.keyframes) == keyframes
    slam.add_scan(4.0, garbage, geometry, (0.6, 0.0, 0.0))
    assert slam.poor_matches == 2 and len(slam.keyframes) == keyframes + 1  # lost for good: map on


@pytest.mark.parametrize("wide_score", [0.2, 0.0])
def test_a_slip_further_than_the_tracking_window_is_found_by_a_second_wider_search(wide_score):
    """A wheel slip can throw the robot further than 3 sigma of odometry's error: the match
    around the prediction is poor, and the scan is searched again over the widest window rather
    than left at odometry's guess, even with match_wide_score set below match_min_score."""
    slam, geometry, angles = slam_tracking_in_a_room()
    slam.config.match_wide_score = wide_score
    slipped = (0.7, 0.4, 0.0)  # odometry says (0.3, 0, 0): 0.57 m off, the window is 0.2 m
    tracked = slam.add_scan(3.0, room_ranges(slipped, angles), geometry, (0.3, 0.0, 0.0))
    assert slam.poor_matches == 0
    assert math.hypot(tracked[0] - slipped[0], tracked[1] - slipped[1]) < 0.03 and abs(tracked[2]) < 0.01


def test_windows_from_the_speeds_pose_to_odometrys_cover_the_way_between():
    positions = positions_towards((0.0, 0.0), (2.5, 0.0), 1.0)
    assert positions[0] == (0.0, 0.0)
    way = [x for x, _ in positions] + [2.5]
    assert all(0.0 < after - before <= 1.0 for before, after in zip(way, way[1:]))
    assert positions_towards((0.0, 0.0), (0.6, 0.0), 1.0) == [(0.0, 0.0)]


LDS_GEOMETRY = ScanGeometry(-math.pi, 2 * math.pi / 360, 360, 0.12, 3.5)  # an LDS-01's full turn
LDS_ANGLES = -math.pi + np.arange(360) * 2 * math.pi / 360


def corridor_world(boxes, end_x, closed_start=False):
    """A corridor 2 m wide along x from -2 m to `end_x`, with `boxes` (world obstacles) in it."""
    walls = [{"type": "wall", "from": [-2.0, y], "to": [end_x, y], "thickness": 0.1} for y in (-1.0, 1.0)]
    if closed_start:
        walls.append({"type": "wall", "from": [-2.0, -1.0], "to": [-2.0, 1.0], "thickness": 0.1})
    return world_from_description({"name": "corridor", "obstacles": boxes + walls})


def test_a_slip_that_reads_a_step_short_is_found_at_the_speed_the_robot_went_on():
    """Scans at 1 Hz in a corridor, the robot going on at 1 m/s, and one step that odometry reads
    as 0.45 m (a slip): within the window around that, the walls alone make a wrong match score
    well; the search around where the robot's speed takes it finds the truth."""
    boxes = [{"type": "box", "center": [x, y], "size": [0.3, 0.3]}
             for x, y in ((1.3, 0.85), (2.9, -0.85), (3.7, 0.85), (5.6, -0.85), (6.2, 0.85), (7.9, -0.85))]
    corridor = corridor_world(boxes, 12.0)
    geometry, angles = LDS_GEOMETRY, LDS_ANGLES
    slam = Slam()
    odometry_x, tracked_x = 0.0, 0.0
    for step in range(8):
        odometry_x += 0.45 if step == 5 else (1.0 if step else 0.0)
        tracked = slam.add_scan(float(step), corridor.raycast(float(step), 0.0, angles, 3.5), geometry,
                                (odometry_x, 0.0, 0.0))
        assert tracked[0] - tracked_x == pytest.approx(1.0 if step else 0.0, abs=0.05), f"scan {step}"
        tracked_x = tracked[0]
    assert slam.poor_matches == 0
    assert slam.odometry_calibration.distance_scale == pytest.approx(1.0, abs=0.02), "a slip teaches no scale"


def test_along_a_featureless_corridor_odometry_that_reads_short_is_corrected_by_what_features_taught():
    """Where the scans cannot tell how far the robot went, the prediction stands: odometry that
    reads 10 % short, corrected by the scale learnt while boxes along the walls pinned each
    match, draws the corridor to near its true length, and the featureless part unlearns nothing."""
    boxes = [{"type": "box", "center": [0.5 + 0.6 * k, 0.85 if k % 2 == 0 else -0.85], "size": [0.3, 0.3]}
             for k in range(6)]
    corridor = corridor_world(boxes, 30.0, closed_start=True)
    geometry, angles = LDS_GEOMETRY, LDS_ANGLES
    slam = Slam()
    learnt = None
    for step in range(121):   # 12 m; beyond 7 m the boxes and the end wall are out of reach
        x = 0.1 * step
        tracked = slam.add_scan(0.2 * step, corridor.raycast(x, 0.0, angles, 3.5), geometry, (0.9 * x, 0.0, 0.0))
        if step == 70:
            learnt = slam.odometry_calibration.distance_scale
    # Learnt over 7 m, against the prior that odometry is right: most of the 11 %.
    assert 1.05 < learnt < 1 / 0.9 + 0.01
    assert slam.odometry_calibration.distance_scale == pytest.approx(learnt, abs=0.005)
    assert tracked[0] == pytest.approx(12.0, abs=0.35)   # odometry alone: 10.8 m


def corridor_keyframes_with_one_wrong_step(walk_xy):
    """A Slam that mapped 4 m of a featureless corridor with exact odometry, then had one tracked
    step between keyframes put 5 cm too long along the corridor (a wrong match where the walls
    cannot say how far the robot went), the keyframes after it moved with it; and that step's index."""
    corridor = corridor_world([], 30.0)
    slam = Slam(SlamConfig(odometry_walk_xy=walk_xy))
    for step in range(41):
        x = 0.1 * step
        slam.add_scan(0.2 * step, corridor.raycast(x, 0.0, LDS_ANGLES, 3.5), LDS_GEOMETRY, (x, 0.0, 0.0))
    wrong = len(slam.keyframes) // 2
    edge = next(edge for edge in slam.graph.edges if (edge.i, edge.j) == (wrong - 1, wrong))
    edge.measurement = (edge.measurement[0] + 0.05,) + edge.measurement[1:]
    slam.graph.poses[wrong:, 0] += 0.05
    return slam, wrong


def step_along(slam, index):
    return relative(tuple(slam.graph.poses[index - 1]), tuple(slam.graph.poses[index]))[0]


def test_the_refinement_keeps_odometrys_step_where_the_scans_leave_the_keyframes_loose():
    slam, wrong = corridor_keyframes_with_one_wrong_step(SlamConfig.DEFAULTS["odometry_walk_xy"])
    odometry_step = slam.keyframes[wrong].odom[0] - slam.keyframes[wrong - 1].odom[0]
    slam.refine()
    assert step_along(slam, wrong) == pytest.approx(odometry_step, abs=0.01)
    # Odometry weighed as if it erred by metres: the wrong step stands, the walls cannot mend it.
    slam, wrong = corridor_keyframes_with_one_wrong_step(100.0)
    slam.refine()
    assert step_along(slam, wrong) == pytest.approx(odometry_step + 0.05, abs=0.01)


def test_an_odometry_step_further_off_than_tracking_could_search_does_not_pull_the_refinement():
    """Odometry reset between two keyframes (5 m, a driver restarted): that step is no measurement."""
    slam, wrong = corridor_keyframes_with_one_wrong_step(SlamConfig.DEFAULTS["odometry_walk_xy"])
    tracked = step_along(slam, wrong)
    for keyframe in slam.keyframes[wrong:]:
        keyframe.odom = (keyframe.odom[0] + 5.0,) + keyframe.odom[1:]
    slam.refine()
    assert step_along(slam, wrong) == pytest.approx(tracked, abs=0.005)


def test_turning_on_the_spot_teaches_how_far_odometry_turns_and_nothing_about_distance():
    """Odometry whose turns read 30 % short (a track width off): a turn on the spot moves its x
    and y not at all, and still teaches the turn scale, by which the next turns are predicted."""
    slam, geometry, angles = slam_tracking_in_a_room()   # at the room's centre, heading 0
    distance_scale = slam.odometry_calibration.distance_scale
    for step in range(1, 11):
        truth = (0.0, 0.0, 0.2 * step)
        tracked = slam.add_scan(2.0 + step, room_ranges(truth, angles), geometry, (0.0, 0.0, 0.14 * step))
        assert abs(tracked[2] - truth[2]) < 0.02
    assert slam.odometry_calibration.turn_scale == pytest.approx(1 / 0.7, rel=0.05)
    assert slam.odometry_calibration.corrected((0.0, 0.0, 0.14))[2] == pytest.approx(0.2, abs=0.01)
    assert slam.odometry_calibration.distance_scale == distance_scale


def test_the_tracking_map_holds_the_keyframes_hits_and_none_of_the_free_space_they_saw():
    """Matching needs only where the obstacles are, and tracing the free space into the fine
    tracking grid took a quarter of the SLAM's time; the published map still traces it."""
    slam, _, _ = slam_tracking_in_a_room()
    local = slam.local_grid
    assert (local.hit_counts > 0).sum() > 100
    assert np.array_equal(local.observations > 0, local.hit_counts > 0)
    published = slam.occupancy_map().data
    assert (published == 0).sum() > (published == 100).sum() > 100


def test_the_local_map_covers_the_last_keyframes_not_the_whole_path():
    """A long corridor must not leave the fine tracking grid as long as the corridor (gigabytes
    on a kilometre of real corridor): it holds the last local_map_keyframes, so its size too."""
    geometry = ScanGeometry(-math.pi / 2, math.pi / 179, 180, 0.1, 10.0)
    angles = -math.pi / 2 + np.arange(180) * math.pi / 179
    with np.errstate(divide="ignore"):
        ranges = np.where(np.sin(angles) != 0, np.abs(1.0 / np.sin(angles)), np.inf)  # walls at y = +-1
    slam = Slam()
    config = slam.config
    step_length = 1.25 * config.keyframe_distance  # every scan a keyframe
    for step in range(240):  # 240 keyframes along the corridor
        slam.add_scan(float(step), ranges, geometry, (step_length * step, 0.0, 0.0))
    growth = 2 * LogOddsGrid.GROWTH * config.match_resolution
    reach = min(config.usable_range, geometry.range_max)
    span = config.local_map_keyframes * step_length + 2 * reach + growth
    assert len(slam.keyframes) > 200
    assert slam.local_grid.shape[1] * config.match_resolution < span < 40.0


def test_a_long_redraw_of_the_map_is_followed_by_a_longer_pause_so_redraws_take_a_bounded_share():
    budget = RedrawBudget(share=0.2)
    assert budget.allows(0.0)
    budget.spent(2.0, now=10.0)  # a 2 s redraw finished at t = 10 s
    assert not budget.allows(17.9) and budget.allows(18.0)
    budget.spent(0.1, now=18.1)
    assert budget.allows(18.5)


def cell_state(occupancy, x, y):
    """The map's value (100 / 0 / -1) at a point; -1 outside."""
    ox, oy = occupancy.origin[:2]
    row, col = int(math.floor((y - oy) / occupancy.resolution)), int(math.floor((x - ox) / occupancy.resolution))
    inside = 0 <= row < occupancy.height and 0 <= col < occupancy.width
    return occupancy.data[row, col] if inside else -1


def occupied_cell_centres_x(occupancy):
    _, cols = np.nonzero(occupancy.data == 100)
    return occupancy.origin[0] + (cols + 0.5) * occupancy.resolution


def test_a_wall_on_the_lattice_is_drawn_in_the_cells_centred_on_it_when_cells_are_shifted_half_a_cell():
    centred = LogOddsGrid(0.05, cell_shift=0.5)
    centred.add_scan(wall_scan(), (0.0, 0.0, 0.0))
    centres = occupied_cell_centres_x(centred.to_occupancy_map())
    assert centres.size > 0 and centres == pytest.approx(np.ones(centres.size))
    # With cell corners on the lattice, the wall at x = 1 is a cell edge: drawn half a cell off.
    cornered = LogOddsGrid(0.05)
    cornered.add_scan(wall_scan(), (0.0, 0.0, 0.0))
    assert np.abs(occupied_cell_centres_x(cornered.to_occupancy_map()) - 1.0).min() == pytest.approx(0.025)


def test_the_published_map_has_a_cell_centred_on_the_map_frame_origin():
    slam = Slam()
    geometry = ScanGeometry(-math.pi / 4, math.pi / 2 / 179, 180, 0.1, 10.0)
    angles = -math.pi / 4 + np.arange(180) * math.pi / 2 / 179
    slam.add_scan(0.0, 1.0 / np.cos(angles), geometry, (0.0, 0.0, 0.0))
    occupancy = slam.occupancy_map()
    corner_in_cells = np.array(occupancy.origin[:2]) / occupancy.resolution
    assert corner_in_cells - np.floor(corner_in_cells) == pytest.approx([0.5, 0.5])
    centres = occupied_cell_centres_x(occupancy)
    assert centres.size > 0 and centres == pytest.approx(np.ones(centres.size))


def test_taking_back_a_scan_restores_the_grid_exactly():
    grid = LogOddsGrid(0.05)
    first = trace_scan(wall_scan(), (0.0, 0.0, 0.0), 0.05)
    second = trace_scan(wall_scan(), (0.2, 0.1, 0.3), 0.05)
    grid.apply(first)
    before = grid.observations.copy(), grid.hit_counts.copy()
    grid.apply(second)
    grid.apply(second, sign=-1)
    assert np.array_equal(grid.observations, before[0])
    assert np.array_equal(grid.hit_counts, before[1])


def test_matcher_finds_a_shifted_and_turned_scan():
    grid = LogOddsGrid(0.025)
    room = room_rays()
    grid.apply(trace_scan(room, (0.0, 0.0, 0.0), 0.025))
    low = np.array([-120, -120])
    matcher = GridMatcher(sparse_likelihood_field((240, 240), *grid.obstacles(low, np.array([240, 240]))),
                          low, 0.025, levels=3)
    truth = (0.07, -0.04, 0.05)
    # The room seen from `truth` is the room's points moved by truth's inverse.
    points = transform_points(inverse(truth), room.hits)
    result = matcher.match(points, (0.0, 0.0, 0.0), 0.2, 0.1)
    assert result.pose == pytest.approx(truth, abs=0.026)
    assert result.score > 0.8


def test_prior_keeps_the_predicted_position_along_a_featureless_corridor():
    geometry = ScanGeometry(-math.pi, 2 * math.pi / 360, 360, 0.1, 3.5)
    angles = -math.pi + np.arange(360) * 2 * math.pi / 360
    with np.errstate(divide="ignore"):
        ranges = np.abs(0.5 / np.sin(angles))  # walls at y = +-0.5, endless along x
    rays = scan_rays(geometry, np.where(ranges < 3.5, ranges, np.inf), 8.0)
    grid = LogOddsGrid(0.025)
    grid.apply(trace_scan(rays, (0.0, 0.0, 0.0), 0.025))
    low = np.array([-160, -40])
    matcher = GridMatcher(sparse_likelihood_field((80, 320), *grid.obstacles(low, np.array([320, 80]))),
                          low, 0.025, levels=3)
    prior = (0.03, 0.0, 0.0)
    result = matcher.match(rays.hits, prior, 0.1, 0.05, prior_sigmas=(0.05, 0.05))
    assert result.pose[0] == pytest.approx(0.03, abs=1e-9)
    assert result.pose[1] == pytest.approx(0.0, abs=0.026)


@pytest.mark.parametrize("half", [1, 2, 4, 8])
def test_the_maxima_grids_taken_over_the_fields_bits_are_its_values_maxima(half):
    rng = np.random.default_rng(half)
    field = rng.random((37, 53)).astype(np.float32)
    field[rng.random(field.shape) < 0.7] = 0.0
    wider = field.copy()
    wider[:, :-half] = np.maximum(field[:, :-half], field[:, half:])
    expected = wider.copy()
    expected[:-half] = np.maximum(wider[:-half], wider[half:])
    maxima = _block_maxima(field, half)
    assert maxima.dtype == np.float32
    assert np.array_equal(maxima, expected)


def room_rays():
    """A 4 x 3 m room with a pillar, seen from the origin: 360 beams."""
    world = load_world_from_text()
    angles = np.arange(360) * 2 * math.pi / 360
    ranges = world.raycast(0.0, 0.0, angles, 3.5)
    geometry = ScanGeometry(0.0, 2 * math.pi / 360, 360, 0.1, 3.5)
    return scan_rays(geometry, ranges, 8.0)


def load_world_from_text():
    return world_from_description({"name": "room", "obstacles": [
        {"type": "wall", "from": [-2.0, -1.5], "to": [2.0, -1.5], "thickness": 0.1},
        {"type": "wall", "from": [2.0, -1.5], "to": [2.0, 1.5], "thickness": 0.1},
        {"type": "wall", "from": [2.0, 1.5], "to": [-2.0, 1.5], "thickness": 0.1},
        {"type": "wall", "from": [-2.0, 1.5], "to": [-2.0, -1.5], "thickness": 0.1},
        {"type": "circle", "center": [0.8, 0.6], "radius": 0.2},
        {"type": "box", "center": [-1.2, -0.9], "size": [0.5, 0.3]}]})


# --- pose graph -------------------------------------------------------------------------------


def test_pose_graph_jacobians_match_finite_differences():
    graph = PoseGraph()
    for pose in [(0.0, 0.0, 0.0), (1.0, 0.2, 0.4), (1.5, 1.1, 2.0)]:
        graph.add_node(pose)
    graph.add_edge(1, 2, (0.7, 0.5, 1.5), np.eye(3))
    i, j, z = np.array([1]), np.array([2]), np.array([[0.7, 0.5, 1.5]])
    _, a, b = graph._errors_and_jacobians(i, j, z)
    for node, jacobian in ((1, a[0]), (2, b[0])):
        for k in range(3):
            step = np.zeros(3)
            step[k] = 1e-6
            graph.poses[node] += step
            plus = graph._errors_and_jacobians(i, j, z)[0][0]
            graph.poses[node] -= 2 * step
            minus = graph._errors_and_jacobians(i, j, z)[0][0]
            graph.poses[node] += step
            assert (plus - minus) / 2e-6 == pytest.approx(jacobian[:, k], abs=1e-5)


def wall(start, end, spacing=0.025):
    """Points every `spacing` m from `start` to `end` (x, y)."""
    count = int(round(math.dist(start, end) / spacing)) + 1
    return np.linspace(start, end, count)


def test_icp_pairs_no_point_on_a_walls_far_face_with_its_near_face():
    """From the next room a scanner sees a wall's other face, its thickness off. Paired with the
    near face's points, those pulled two scans together by as much (keyframes through a doorway
    in the simulated house: 0.10-0.11 m off, and the refined map worse than the unrefined one)."""
    rooms = [wall((-1.0, 1.5), (3.5, 1.5)), wall((3.5, -1.0), (3.5, 1.5))]
    seen_from_here = np.concatenate(rooms + [wall((1.0, -1.0), (1.0, 0.5))])
    there = (2.3, 0.0, 0.0)
    seen_from_there = transform_points(inverse(there), np.concatenate(rooms + [wall((1.15, -1.0), (1.15, 0.5))]))
    target = LineCloud(seen_from_here)
    pose, _ = align(target, seen_from_there, there)
    assert pose == pytest.approx(there, abs=1e-3)
    assert target.points_on_lines(seen_from_there, there) == sum(len(points) for points in rooms)


def test_loop_edge_pulls_a_drifted_square_back_together():
    truth = [(0.0, 0.0, 0.0), (1.0, 0.0, math.pi / 2), (1.0, 1.0, math.pi), (0.0, 1.0, -math.pi / 2)]
    graph, drifted = PoseGraph(), [truth[0]]
    odometry = [relative(truth[k], truth[k + 1]) for k in range(3)]
    for step in odometry:
        drifted.append(compose(drifted[-1], (step[0] * 1.05, step[1], step[2] + 0.05)))
    for pose in drifted:
        graph.add_node(pose)
    information = np.diag([100.0, 100.0, 400.0])
    for k in range(3):
        graph.add_edge(k, k + 1, relative(drifted[k], drifted[k + 1]), information)
    graph.add_edge(3, 0, relative(truth[3], truth[0]), information * 10, robust=True)
    before = graph.chi2()
    graph.optimize()
    assert graph.chi2() < before / 10
    error = np.hypot(*(graph.poses[3, :2] - truth[3][:2]))
    assert error < np.hypot(*(np.array(drifted[3][:2]) - truth[3][:2])) / 2


def test_the_pose_graph_repeats_itself_bit_for_bit_wherever_its_arrays_lie_in_memory():
    """NumPy's AVX-512 sines of a strided column get last bits that depend on its address; one
    such bit once decided a loop closure, so two runs of one log gave different maps."""
    rng = np.random.default_rng(4)
    count = 300
    truth = [(3.0 * math.cos(a), 3.0 * math.sin(a), wrap_angle(a + math.pi / 2))
             for a in np.linspace(0.0, 2 * math.pi, count, endpoint=False)]
    template = PoseGraph()
    for pose in truth:
        template.add_node(tuple(np.add(pose, rng.normal(0.0, 0.05, 3))))
    for k in range(count):
        step = relative(truth[k], truth[(k + 1) % count])
        template.add_edge(k, (k + 1) % count, tuple(np.add(step, rng.normal(0.0, 0.01, 3))), np.eye(3) * 100.0)
    results = set()
    for shift in range(16):
        graph = copy.deepcopy(template)
        buffer = np.zeros(3 * count + shift)  # the poses, and what the optimisation allocates, lie elsewhere each time
        graph.poses = buffer[shift:].reshape(count, 3)
        graph.poses[:] = template.poses
        graph.optimize()
        results.add(graph.poses.tobytes())
    assert len(results) == 1


# --- configuration ----------------------------------------------------------------------------


def room_corner_points(pose):
    """Points every 2.5 cm on a room's corner walls (x = 2, y = 1.5), seen from `pose`."""
    along = np.arange(-1.5, 1.5, 0.025)
    walls = np.concatenate((np.column_stack((np.full_like(along, 2.0), along)),
                            np.column_stack((along + 0.5, np.full_like(along, 1.5)))))
    return transform_points(inverse(pose), walls)


def keyframe_of_hits(hits, travel, geometry):
    """A keyframe whose scan hit `hits` (robot frame), matching one point in four."""
    return Keyframe(travel, ScanRays(geometry, hits, np.zeros((0, 2))), hits[::4], travel, (travel, 0.0, 0.0))


def keyframe_seeing_room_corner(pose, travel):
    return keyframe_of_hits(room_corner_points(pose), travel, ScanGeometry(-math.pi / 2, 0.01, 315, 0.0, math.inf))


def keyframes_seeing(old_hits, new_hits):
    """Two keyframes, 50 m of path apart, whose full-circle scans hit these."""
    geometry = ScanGeometry(-math.pi, 0.01, 628, 0.0, math.inf)
    return keyframe_of_hits(old_hits, 0.0, geometry), keyframe_of_hits(new_hits, 50.0, geometry)


def test_a_loop_closure_the_two_keyframes_own_scans_contradict_is_refused():
    """A match of the recent scans against the old map can be right while the edge it makes to
    the old keyframe is wrong, if that keyframe sits wrong among its neighbours."""
    config = SlamConfig()
    old_pose, new_pose = (0.0, 0.0, 0.0), (0.3, -0.2, 0.4)
    old, new = keyframe_seeing_room_corner(old_pose, 0.0), keyframe_seeing_room_corner(new_pose, 10.0)
    truth = relative(old_pose, new_pose)
    assert keyframes_agree(old, new, truth, config)
    assert not keyframes_agree(old, new, compose(truth, (0.4, 0.0, 0.0)), config)
    assert not keyframes_agree(old, new, compose(truth, (0.0, 0.0, 0.05)), config)


def corridor_with_doors_points(x_from, x_to, pose, period=1.0, door=0.4):
    """Points every 2.5 cm on a corridor's walls (y = +-1) between x_from and x_to, with a door
    `door` m wide every `period` metres, seen from `pose`."""
    along = np.arange(x_from, x_to, 0.025)
    wall = along[np.mod(along, period) < period - door]
    walls = np.concatenate((np.column_stack((wall, np.full_like(wall, 1.0))),
                            np.column_stack((wall, np.full_like(wall, -1.0)))))
    return transform_points(inverse(pose), walls)


def test_a_loop_closure_in_a_corridor_whose_doors_repeat_is_refused():
    """In a corridor whose doors repeat, two keyframes' scans fit as well one door apart: ICP
    from a closure's pose agrees with it, and only a start further along shows the other fit."""
    old_pose, new_pose = (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)
    old_hits = corridor_with_doors_points(-8.0, 8.0, old_pose)
    new_hits = corridor_with_doors_points(-5.0, 7.0, new_pose)
    config = SlamConfig()
    old, new = keyframes_seeing(old_hits, new_hits)
    one_door_short = (0.0, 0.0, 0.0)
    aligned, _ = align(LineCloud(old_hits), new_hits, one_door_short)
    assert within_check(aligned, one_door_short, config)  # the scans alone agree with the look-alike
    assert not keyframes_agree(old, new, one_door_short, config)


def test_a_loop_closure_probes_for_look_alikes_as_far_as_its_search_reached():
    """After a long drift the loop search reaches metres along a corridor, and so may a
    look-alike: a corridor whose wide doors repeat every 3 m fits as well one door further on."""
    old_pose, new_pose = (0.0, 0.0, 0.0), (3.0, 0.0, 0.0)
    old_hits = corridor_with_doors_points(-12.0, 12.0, old_pose, period=3.0, door=0.8)
    new_hits = corridor_with_doors_points(-6.0, 9.0, new_pose, period=3.0, door=0.8)
    old, new = keyframes_seeing(old_hits, new_hits)
    one_door_short = (0.0, 0.0, 0.0)
    assert keyframes_agree(old, new, one_door_short, SlamConfig(), window=1.0)  # a metre's probes cannot tell
    assert not keyframes_agree(old, new, one_door_short, SlamConfig(), window=3.5)


def test_a_loop_closure_is_refused_when_a_look_alike_fits_almost_as_well():
    """On infinite-corridor the scans fit a look-alike door 4.7 m along better than the true
    place: a margin is needed. Here only a short stub on one wall, which both scanners see from
    the same side, tells the true place from the look-alike a door further on."""
    def stub(pose):
        along = np.arange(0.1, 1.0, 0.025)
        return transform_points(inverse(pose), np.column_stack((np.full_like(along, 4.5), along)))

    old_pose, new_pose = (0.0, 0.0, 0.0), (3.0, 0.0, 0.0)
    old_hits = np.concatenate((corridor_with_doors_points(-12.0, 12.0, old_pose, period=3.0, door=0.8),
                               stub(old_pose)))
    new_hits = np.concatenate((corridor_with_doors_points(-6.0, 9.0, new_pose, period=3.0, door=0.8),
                               stub(new_pose)))
    old, new = keyframes_seeing(old_hits, new_hits)
    right = relative(old_pose, new_pose)
    assert not keyframes_agree(old, new, right, SlamConfig(), window=3.5)
    # only a look-alike that fits at least as well
    assert keyframes_agree(old, new, right, SlamConfig(), window=3.5, fit_share=1.0)


def test_the_loop_search_widens_with_the_path_between_the_keyframes_a_closed_loop_a_shortcut():
    config = SlamConfig()
    drift_path = DriftPath()
    travel = np.array([0.0, 100.0, 200.0, 300.0, 400.0])  # keyframes 100 m of path apart
    drift_path.extend(0.0)
    for _ in travel[1:]:
        drift_path.extend(100.0)
    assert drift_path.metres == pytest.approx([400.0, 300.0, 200.0, 100.0, 0.0])
    assert drift_path.windows(config, 5) == pytest.approx(
        [config.loop_window_max_xy, config.loop_drift * 300.0, config.loop_drift * 200.0, config.loop_drift * 100.0,
         config.loop_window_xy])
    drift_path.shorten(travel, LoopClosure(1, 3, (0.0, 0.0, 0.0), 0.9, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    # Keyframe 3 was found back at keyframe 1, 100 m of path before the newest one.
    assert drift_path.metres == pytest.approx([200.0, 100.0, 200.0, 100.0, 0.0])


def test_a_loop_closure_between_keyframes_that_overlap_too_little_to_judge_is_refused():
    """Unjudged closures were the false ones on freiburg-079: a missed loop costs a little
    drift, a false one a broken map."""
    old_pose, new_pose = (0.0, 0.0, 0.0), (0.3, -0.2, 0.4)
    old, new = keyframe_seeing_room_corner(old_pose, 0.0), keyframe_seeing_room_corner(new_pose, 10.0)
    new.rays.hits = new.rays.hits[:10]
    assert not keyframes_agree(old, new, relative(old_pose, new_pose), SlamConfig())


def straight_drive(keyframes=60, spacing=0.3):
    """Keyframes every `spacing` m along x, chained by their tracked steps as the SLAM chains them,
    and a LoopCloser that saw them join: (graph, keyframes, loop closer)."""
    config = SlamConfig()
    loops = LoopCloser(config)
    graph = PoseGraph()
    odometry = diagonal_information(config.odometry_sigma_xy, config.odometry_sigma_theta)
    for k in range(keyframes):
        graph.add_node((spacing * k, 0.0, 0.0))
        if k:
            graph.add_edge(k - 1, k, (spacing, 0.0, 0.0), odometry)
        loops.drift_path.extend(spacing if k else 0.0)
    return graph, [Keyframe(k, None, None, spacing * k, (spacing * k, 0.0, 0.0)) for k in range(keyframes)], loops


def closure_moving_the_map(graph, old, newest, shift):
    """A closure saying keyframe `newest` lies `shift` m further along x from keyframe `old` than the graph has it."""
    at = tuple(graph.poses[newest])
    moved = (at[0] + shift, at[1], at[2])
    return LoopClosure(old, newest, relative(tuple(graph.poses[old]), moved), 0.9, (shift, 0.0, 0.0), at)


def loop_edges(graph):
    return [(edge.i, edge.j) for edge in graph.edges if edge.robust]


def test_a_loop_closure_is_taken_only_once_a_second_one_moves_the_map_alike_and_soon_enough():
    """Corridors that look alike fool one match; two from different places rarely agree on the
    same wrong correction. A closure left without a partner for loop_pending_keyframes is dropped."""
    graph, keyframes, loops = straight_drive()
    loops.consider(closure_moving_the_map(graph, 0, 30, 0.15), keyframes, graph, graph.optimize)
    assert loop_edges(graph) == [] and loops.closures == []
    loops.consider(closure_moving_the_map(graph, 5, 32, -0.5), keyframes, graph, graph.optimize)  # disagrees
    assert loop_edges(graph) == []
    loops.consider(closure_moving_the_map(graph, 1, 33, 0.15), keyframes, graph, graph.optimize)
    assert loop_edges(graph) == [(0, 30), (1, 33)]
    assert [(old, newest) for old, newest, _, _ in loops.closures] == [(0, 30), (1, 33)]
    assert graph.poses[33, 0] - graph.poses[1, 0] > 0.3 * 32 + 0.05  # the graph took the correction
    # The disagreeing closure waited since keyframe 32: one agreeing with it 11 keyframes later is too late.
    loops.consider(closure_moving_the_map(graph, 6, 43, -0.5), keyframes, graph, graph.optimize)
    assert loop_edges(graph) == [(0, 30), (1, 33)] and loops.rejected == 0


def test_closures_too_small_to_move_the_map_wait_in_the_graph_until_the_map_is_next_published():
    graph, keyframes, loops = straight_drive()
    before = graph.poses.copy()
    for old, newest in ((0, 30), (1, 32)):  # 1 cm: under half a cell, not worth a redraw on its own
        loops.consider(closure_moving_the_map(graph, old, newest, 0.01), keyframes, graph, graph.optimize)
    assert loop_edges(graph) == [(0, 30), (1, 32)]
    assert graph.poses == pytest.approx(before, abs=1e-9)
    loops.optimize_deferred(graph.optimize)
    assert graph.poses[32, 0] - before[32, 0] > 0.005


def test_agreeing_loop_closures_that_the_optimised_graph_still_contradicts_are_taken_out_again():
    graph, keyframes, loops = straight_drive()
    before = graph.poses.copy()
    for old, newest in ((0, 30), (1, 32)):  # 3 m against 30 keyframes of tracking: not the same place
        loops.consider(closure_moving_the_map(graph, old, newest, 3.0), keyframes, graph, graph.optimize)
    assert loop_edges(graph) == [] and loops.closures == []
    assert loops.rejected == 2
    assert graph.poses == pytest.approx(before, abs=1e-6)


def test_a_loop_closure_joins_the_old_keyframe_that_looked_the_same_way():
    """Of the old keyframes around the match, the nearest one looking back the other way shares
    little of the newest keyframe's view; one a little farther, looking the same way, shares it."""
    poses = np.array([(0.0, 0.0, math.pi), (0.5, 0.0, 0.1), (3.0, 0.0, 0.0)])
    assert nearest_view(poses, [0, 1, 2], (0.1, 0.0, 0.0)) == 1


def test_unknown_or_bad_slam_parameters_are_rejected_with_their_names():
    with pytest.raises(ValueError, match="unknown SLAM parameter.*particles"):
        SlamConfig(particles=30)
    with pytest.raises(ValueError, match="resolution must be positive"):
        SlamConfig(resolution=0)
    with pytest.raises(ValueError, match="local_map_keyframes must be a positive integer"):
        SlamConfig(local_map_keyframes=2.5)
    with pytest.raises(ValueError, match="loop_window_max_xy .* must be at least loop_window_xy"):
        SlamConfig(loop_window_xy=2.0, loop_window_max_xy=1.0)


def test_slam_methods_map_to_upstream_node_names_and_unknown_ones_list_the_known():
    assert check_slam_method("gmapping") == "turtlebot3_slam_gmapping"
    assert check_slam_method("karto") == "slam_karto"
    with pytest.raises(ValueError, match="unknown slam_methods 'hector': known methods are gmapping, karto"):
        check_slam_method("hector")


# --- whole runs in the simulator --------------------------------------------------------------


def simulated_run(world_name, route, scan=None, seed=1, noise=None, model="burger"):
    """Drive a route in the simulator, feeding SLAM; returns (slam, true poses per scan, odometry per scan)."""
    world = load_world(world_name)
    sim = Simulation(world, model=model, pose=world.spawn_pose, seed=seed, noise=noise or NoiseConfig())
    mount = sim.model.scan_mount
    slam, truth, odometry = Slam(SlamConfig()), [], []
    scan = scan or default_scan

    def on_scan(simulation):
        geometry, ranges = scan(simulation, world, (mount[0], mount[1], 0.0))
        odom = simulation.odometry[:3]
        slam.add_scan(simulation.time, ranges, geometry, odom)
        truth.append(simulation.pose)
        odometry.append(odom)
    assert drive_route(sim, route, 0.2, on_scan, timeout=1200), "the route hit an obstacle"
    return slam, world, truth, odometry


def default_scan(simulation, world, mount):
    scan = simulation.scan()
    geometry = ScanGeometry(scan.angle_min, scan.angle_increment, len(scan.ranges), scan.range_min, scan.range_max,
                            mount)
    return geometry, scan.ranges


def map_quality(slam, world, truth):
    occupancy_map = slam.occupancy_map()
    occupied = world.rasterize(occupancy_map.resolution, occupancy_map.origin[:2], occupancy_map.width,
                               occupancy_map.height)
    ate = absolute_trajectory_error([pose[1:] for pose in slam.trajectory()], truth)[0]
    return cell_agreement(occupancy_map.data, occupied), occupied_precision(occupancy_map.data, occupied), ate


def test_map_of_turtlebot3_world_matches_ground_truth_despite_odometry_drift():
    slam, world, truth, odometry = simulated_run("turtlebot3_world", ROUTES["turtlebot3_world"])
    agreement, precision, ate = map_quality(slam, world, truth)
    odometry_error = absolute_trajectory_error(odometry, truth)[0]
    assert agreement >= 0.95
    assert precision >= 0.95
    assert ate <= 0.05
    assert ate < odometry_error
    x, y, yaw = compose(slam.map_to_odom, odometry[-1])
    assert (x, y, yaw) == pytest.approx(slam.pose)


@pytest.fixture(scope="module")
def house_run():
    """The house loop driven twice as far off by odometry as the simulator's default, three times."""
    return simulated_run("house", ROUTES["house"], noise=NoiseConfig()._replace(
        odom_linear_drift=0.03, odom_angular_drift=0.03, wheel_slip=0.015))


def test_redrawing_the_map_outside_the_slam_gives_the_same_map_unless_keyframes_moved_again(house_run):
    slam = copy.deepcopy(house_run[0])  # optimising again moves keyframes: the other tests see the run as it was
    slam._optimize()  # as a loop closure does: keyframes may move, the map is outdated
    assert slam.map_outdated
    stale = slam.map_rebuild()
    stale.run()
    slam._optimize()  # another loop closure meanwhile
    assert not slam.adopt(stale)
    fresh = slam.map_rebuild()
    fresh.run()
    assert slam.adopt(fresh)
    assert not slam.map_outdated
    redrawn_in_place = Slam(slam.config)
    redrawn_in_place.keyframes, redrawn_in_place.graph = slam.keyframes, slam.graph
    redrawn_in_place._global_dirty = True
    assert redrawn_in_place.occupancy_map() == slam.occupancy_map()


def test_house_loop_closes_without_a_doubled_wall(house_run):
    slam, world, truth, _ = house_run
    agreement, precision, ate = map_quality(slam, world, truth)
    assert slam.loops.closures
    # A doubled wall puts many occupied cells off every true wall: 0.85 with no loop closed, 0.96 here.
    assert precision >= 0.95
    assert agreement >= 0.95
    assert ate <= 0.06


def test_the_house_map_takes_in_the_closures_that_waited_before_it_is_published(house_run):
    slam, world, truth, _ = house_run
    slam = copy.deepcopy(slam)
    # Which closures are left waiting at the end is decided by the run's last bits: a change to
    # how the SLAM computes may leave none, and this test then needs another run that does.
    assert slam.loops.deferred, "the house run no longer ends with loop closures waiting"
    slam.optimize_deferred_closures()
    assert slam.map_outdated
    _, precision, _ = map_quality(slam, world, truth)
    assert precision >= 0.97  # 0.962 as the run left it


def half_circle_long_range_scan(simulation, world, mount):
    """180 beams over 180 degrees (forward half), 80 m range, with NaN and zero (no measurement) returns."""
    geometry = ScanGeometry(-math.pi / 2, math.pi / 179, 180, 0.05, 80.0, mount)
    x, y, yaw = simulation.scan_pose()
    angles = -math.pi / 2 + np.arange(180) * math.pi / 179
    ranges = world.raycast(x, y, yaw + angles, 80.0)
    rng = np.random.RandomState(int(simulation.time * 1000) % 2 ** 31)
    ranges = ranges + rng.normal(0.0, 0.01, 180)
    ranges[rng.rand(180) < 0.05] = np.nan
    ranges[rng.rand(180) < 0.05] = 0.0
    return geometry, ranges


def test_any_scan_geometry_maps_the_house_half_circle_lidar_with_long_range_and_dropouts():
    slam, world, truth, _ = simulated_run("house", ROUTES["house"][:12], scan=half_circle_long_range_scan)
    agreement, precision, ate = map_quality(slam, world, truth)
    assert agreement >= 0.95
    assert precision >= 0.95
    assert ate <= 0.05
