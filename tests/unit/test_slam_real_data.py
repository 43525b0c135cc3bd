"""SLAM on real laser data (a Radish log, benchmarks/data/radish) with odometry as wrong as a real robot's.

Our simulator's odometry is kinder than a carpet, a bump or a turn on the spot: these tests
would have caught SLAM that is as wrong as raw odometry on real scans.
"""
import math

import numpy as np
import pytest

from benchmarks import scan_consistency
from testkit.real_data import load_log, run_slam, run_slam_with, score
from turtlebot3c_common.se2 import compose, relative
from turtlebot3c_sim.evaluation import false_relations, relative_pose_errors
from turtlebot3c_sim.odometry_error import SEVERITIES, OdometryError, noisy_odometry, with_slip

REGRESSION_LOG, REGRESSION_SCANS = "freiburg-101", 150


@pytest.fixture(scope="module")
def log():
    return load_log(REGRESSION_LOG, REGRESSION_SCANS)


def test_a_radish_log_reads_as_a_half_turn_scan_with_no_returns_marked(log):
    assert log.ranges.shape == (REGRESSION_SCANS, 360)
    assert log.angle_min == pytest.approx(-math.pi / 2)
    assert log.angle_increment == pytest.approx(math.radians(0.5))
    assert np.isinf(log.ranges).any(), "SICK's 81.91 m 'no return' must not read as an echo"
    assert np.isfinite(log.ranges).mean() > 0.5
    assert (np.diff(log.stamps) > 0).all()


def test_the_severe_odometry_error_is_as_bad_as_a_real_robot_and_seeded(log):
    first = noisy_odometry(log.reference, SEVERITIES["severe"], seed=3)
    assert np.array_equal(first, noisy_odometry(log.reference, SEVERITIES["severe"], seed=3))
    assert not np.array_equal(first, noisy_odometry(log.reference, SEVERITIES["severe"], seed=4))
    path = np.hypot(*np.diff(first[:, :2], axis=0).T).sum()
    assert abs(path / log.travel()[-1] - 1.0) > 0.05
    odometry = relative_pose_errors(first, log.reference, log.travel())
    assert odometry.translation > 0.3 and math.degrees(odometry.rotation) > 5.0


def test_a_slip_reads_a_step_long_as_often_as_short(log):
    """A wheel spinning on a smooth floor reads long, a robot pushed or skidding reads short."""
    slips_only = OdometryError(0.0, 0.0, 0.0, 0.0, 0.0, slip_per_metre=100.0, slip_loss=0.5, slip_turn=0.0)
    odometry = noisy_odometry(log.reference, slips_only, seed=1)
    truth, read = (np.hypot(*np.diff(poses[:, :2], axis=0).T) for poses in (log.reference, odometry))
    ratio = read[truth > 0.05] / truth[truth > 0.05]
    assert ratio.min() >= 0.5 - 1e-9 and ratio.max() <= 1.5 + 1e-9
    assert (ratio > 1.05).mean() > 0.3 and (ratio < 0.95).mean() > 0.3


def test_a_slip_put_at_one_step_reads_it_as_asked_and_moves_the_rest_of_the_path_with_it(log):
    odometry = noisy_odometry(log.reference, SEVERITIES["severe"], seed=1)
    slipped = with_slip(odometry, 50, 0.3)
    def step(poses, i):
        return relative(tuple(poses[i - 1]), tuple(poses[i]))
    slipped_step, before = step(slipped, 50), step(odometry, 50)
    assert math.hypot(slipped_step[0], slipped_step[1]) == pytest.approx(0.3)
    assert math.atan2(slipped_step[1], slipped_step[0]) == pytest.approx(math.atan2(before[1], before[0]))
    assert slipped_step[2] == pytest.approx(before[2])
    assert np.array_equal(slipped[:50], odometry[:50])
    for i in range(51, len(odometry)):
        assert step(slipped, i) == pytest.approx(step(odometry, i))


def test_the_relations_metric_ignores_where_the_map_frame_lies_but_not_a_bent_path(log):
    moved = np.array([compose((5.0, -2.0, 1.0), tuple(pose)) for pose in log.reference])
    unmoved = relative_pose_errors(moved, log.reference, log.travel())
    assert unmoved.translation == pytest.approx(0.0, abs=1e-9) and unmoved.pairs > 100
    bent = log.reference.copy()
    bent[len(bent) // 2:, 2] += 0.05
    assert relative_pose_errors(bent, log.reference, log.travel()).rotation > 0.002  # pairs across the bend


def test_a_loop_closure_that_contradicts_the_reference_is_counted_false(log):
    right = (0, 40, relative(tuple(log.reference[0]), tuple(log.reference[40])))
    wrong = (0, 40, tuple(np.add(right[2], (1.0, 0.0, 0.0))))
    assert false_relations([right], log.reference) == 0
    assert false_relations([right, wrong], log.reference) == 1


def test_slam_on_real_scans_with_severe_odometry_stays_close_to_the_reference_with_no_false_loop(log):
    run = run_slam(log, "severe", seed=1)
    ours, odometry = score(log, run.trajectory, run.closures), score(log, run.odometry)
    assert ours.translation < 0.08 and ours.rotation < 0.8, ours
    assert ours.translation < 0.1 * odometry.translation, (ours, odometry)
    assert ours.false_closures == 0, run.closures


def test_slam_tracks_sparse_real_scans_that_each_see_much_new_ground():
    """orebro: 180-degree scans 1-3 m and up to 40 degrees apart. A right match there scores
    0.08-0.2, as much of each scan falls where the map has seen nothing yet; a threshold of 0.2
    left one scan in eight on odometry's guess (0.28 m / 6.6 degrees, severe odometry)."""
    log = load_log("orebro")
    run = run_slam(log, "severe", seed=1)
    ours = score(log, run.trajectory, run.closures)
    assert ours.translation < 0.2 and ours.rotation < 2.5, ours
    assert ours.false_closures == 0, run.closures


def test_slam_tracks_an_open_hall_by_walls_beyond_8_m():
    """edmonton, a convention centre: 44 % of the hits lie beyond 8 m. Cut at 8 m, the scans
    held little to track (0.12 m / 0.94 degrees, severe odometry). Without the refinement at
    the end (Slam.refine), tracking and loop closures left 0.080 m / 0.48 degrees; with it,
    0.065 / 0.42."""
    log = load_log("edmonton")
    run = run_slam(log, "severe", seed=1)
    ours = score(log, run.trajectory, run.closures)
    assert ours.translation < 0.072 and ours.rotation < 0.46, ours
    assert ours.false_closures == 0, run.closures


def test_slam_closes_no_loop_to_a_look_alike_stretch_of_a_long_corridor():
    """infinite-corridor, odometry seed 3: scan 363 was joined to scan 222 half a metre along
    the corridor from where both the reference and their scans put it; ICP from the closure's
    pose had stopped where a few door frames lined up, and agreed with it. Along this corridor
    the reference and the scans disagree by up to 0.5 m on other pairs, and which closures
    each disputes varies with numpy's build, so a closure counts as false here when both do."""
    log = load_log("infinite-corridor", 370)
    run = run_slam(log, "severe", seed=3)
    scans = scan_consistency.ScanSet(log)
    false = [closure for closure in run.closures if false_relations([closure], log.reference) and
             scan_consistency.false_by_scans(scans, [closure], log.reference)]
    assert not false, false
    assert len(run.closures) >= 10, "the corridor's other loops still close"


def test_slam_keeps_its_heading_turning_on_the_spot_with_odometry_whose_turns_read_short():
    """fhw, odometry seed 3, whose turns read 30 % short. From scan 55 the robot turns back and
    forth on the spot, and each 180-degree scan sees new ground: the matches, too weak to
    overrule odometry's prediction, followed it for five scans, and the rest of the map turned
    45 degrees (over these 80 scans, 0.54 m / 11 degrees). The turn scale learnt from the turns
    before predicts them right (0.12 m / 1.2 degrees)."""
    log = load_log("fhw", 80)
    run = run_slam(log, "severe", seed=3)
    ours = score(log, run.trajectory)
    assert ours.translation < 0.2 and ours.rotation < 2.5, ours


def step_error(log, run, before, after):
    """How far our motion from scan `before` to scan `after` is from the reference's (x, y, yaw)."""
    return relative(relative(tuple(log.reference[before]), tuple(log.reference[after])),
                    relative(tuple(run.trajectory[before]), tuple(run.trajectory[after])))


def test_a_doubtful_match_is_searched_for_over_the_widest_window_too():
    """orebro, odometry seed 4: at scan 75 a slip reads a 1.45 m step turning 21 degrees as
    0.51 m turning 10, while the robot had gone 2 m a scan. The truth lay outside the tracking
    window; searched there alone, the scans 75-79 came out 1.1 m and 16 degrees off (first
    seen on acapulco, where the pose taken 20 degrees off turned the rest of the map)."""
    log = load_log("orebro", 80)
    run = run_slam(log, "severe", seed=4)
    error = step_error(log, run, 74, 79)
    assert math.hypot(error[0], error[1]) < 0.1 and abs(math.degrees(error[2])) < 2.0, error


def test_a_slip_that_reads_a_step_short_is_found_where_the_robots_speed_takes_it():
    """belgioioso, 1 Hz scans: at scan 93 a slip reads a 1.03 m step as 0.63 m (severe odometry
    of seed 1 drew it so before its slips read long as well as short). The truth lay outside the
    tracking window, and inside it a pose 0.45 m short scored 0.27: taken, it put that part of
    the map 0.25-0.5 m short. The robot had gone on at 1 m/s."""
    log = load_log("belgioioso", 100)
    run = run_slam_with(log, with_slip(noisy_odometry(log.reference, SEVERITIES["severe"], 1), 93, 0.63))
    error = step_error(log, run, 92, 94)
    assert math.hypot(error[0], error[1]) < 0.1, error


def test_a_slip_that_reads_a_step_long_is_found_between_where_the_wheels_and_the_speed_put_it():
    """orebro, 1 Hz scans: at scan 36 a slip reads a 3.0 m step as 4.2 m (severe odometry of seed
    2), while the robot's speed says 2.0 m. The truth lay outside the window around either, and
    the scan kept odometry's guess: the rest of the map 1.6 m off."""
    log = load_log("orebro", 40)
    run = run_slam_with(log, with_slip(noisy_odometry(log.reference, SEVERITIES["severe"], 2), 36, 4.2))
    error = step_error(log, run, 35, 37)
    assert math.hypot(error[0], error[1]) < 0.1, error


def test_slam_closes_the_big_loop_after_two_hundred_metres_of_path():
    """fhw, severe odometry: back at the start after ~200 m of path the map had drifted 3-10 m
    and 13 degrees, beyond the fixed 1 m loop search; the walls of the whole floor were drawn
    twice (ATE 1.6-2.8 m). The search now widens with the path since the last closure."""
    log = load_log("fhw")
    run = run_slam(log, "severe", seed=1)
    ours = score(log, run.trajectory, run.closures)
    scans = scan_consistency.ScanSet(log)
    false = [closure for closure in run.closures if false_relations([closure], log.reference) and
             scan_consistency.false_by_scans(scans, [closure], log.reference)]
    assert ours.ate < 0.6, ours
    assert not false, false
