"""Learning how odometry errs from the scan matches (turtlebot3c_slam.odometry_calibration): how
far the robot goes per metre odometry reads, how far it turns per radian, how its heading drifts."""
import numpy as np
import pytest

from turtlebot3c_slam.odometry_calibration import (
    SCALE_LIMITS,
    TURN_SCALE_LIMITS,
    OdometryCalibration,
    firmness_along_heading,
)


def test_a_fresh_calibration_trusts_odometry():
    assert OdometryCalibration().corrected((0.3, 0.05, 0.2)) == (0.3, 0.05, 0.2)


def test_it_learns_how_far_odometry_reads_short_and_corrects_the_next_steps():
    calibration = OdometryCalibration()
    random = np.random.RandomState(1)
    for _ in range(200):   # 10 m of 5 cm steps, read 10 % short, matched to 1 cm
        calibration.learn_distance((0.045, 0.0, 0.01), (0.05 + random.normal(0, 0.01), 0.0, 0.01), 1.0)
    assert calibration.corrected((0.09, 0.0, 0.3)) == pytest.approx((0.1, 0.0, 0.3), rel=0.03)


def test_a_backward_step_is_corrected_as_a_forward_one():
    calibration = OdometryCalibration()
    for _ in range(100):
        calibration.learn_distance((-0.09, 0.0, 0.0), (-0.1, 0.0, 0.0), 1.0)
    assert calibration.distance_scale == pytest.approx(1 / 0.9, rel=0.02)


def test_matches_that_did_not_pin_the_motion_teach_nothing():
    """Along a featureless corridor the match is the prediction, whatever calibration it was made with."""
    calibration = OdometryCalibration()
    for _ in range(100):
        calibration.learn_distance((0.09, 0.0, 0.0), (0.1, 0.0, 0.0), 1.0)
    learnt = calibration.distance_scale
    for _ in range(400):   # 36 m, nearly twice the memory
        calibration.learn_distance((0.09, 0.0, 0.0), (0.09, 0.0, 0.0), firmness=0.0)
    assert calibration.distance_scale == pytest.approx(learnt, rel=1e-3)


def test_matches_that_make_no_sense_as_odometry_are_bounded():
    calibration = OdometryCalibration()
    for _ in range(50):
        calibration.learn_distance((0.1, 0.0, 0.0), (0.5, 0.0, 0.0), 1.0)
    assert calibration.distance_scale == SCALE_LIMITS[1]


def test_what_was_learnt_fades_with_the_path_so_a_new_floor_is_followed():
    calibration = OdometryCalibration(memory=5.0)
    for _ in range(200):   # 60 m (12 memories) of 0.3 m steps on a floor where odometry reads 10 % short
        calibration.learn_distance((0.27, 0.0, 0.0), (0.3, 0.0, 0.0), 1.0)
    assert calibration.distance_scale == pytest.approx(1 / 0.9, rel=0.01)
    for _ in range(200):   # then 60 m where it reads 5 % long
        calibration.learn_distance((0.315, 0.0, 0.0), (0.3, 0.0, 0.0), 1.0)
    assert calibration.distance_scale == pytest.approx(1 / 1.05, rel=0.01)


def test_a_room_pins_the_motion_along_the_heading_and_a_corridor_does_not():
    along = np.linspace(-3.0, 3.0, 121)
    left, right = (np.column_stack((along, np.full_like(along, side))) for side in (1.0, -1.0))
    corridor = np.concatenate((right, left[::-1]))
    assert firmness_along_heading(corridor) < 0.01
    across = np.linspace(-1.0, 1.0, 41)
    ahead, behind = (np.column_stack((np.full_like(across, end), across)) for end in (3.0, -3.0))
    room = np.concatenate((right, ahead, left[::-1], behind[::-1]))
    assert 0.45 < firmness_along_heading(room) < 0.6   # the walls facing it are a quarter of the points
    assert firmness_along_heading(ahead) == 1.0
    assert firmness_along_heading(corridor[:2]) == 0.0


def test_it_learns_how_far_turns_read_short_and_corrects_the_next_turns():
    """A track width off, or wheels that skid turning on carpet: turns read 30 % short."""
    calibration = OdometryCalibration()
    random = np.random.RandomState(1)
    for _ in range(20):   # turns on the spot of 0.2-0.6 rad either way, matched to 0.01 rad
        turn = random.choice((-1, 1)) * random.uniform(0.2, 0.6)
        calibration.learn_turn((0.0, 0.0, 0.7 * turn), (0.0, 0.0, turn + random.normal(0, 0.01)))
    assert calibration.corrected((0.0, 0.0, 0.35)) == pytest.approx((0.0, 0.0, 0.5), abs=0.01)


def test_it_tells_a_heading_that_drifts_as_the_robot_drives_from_turns_that_read_short():
    """Wheels of unequal radii turn the robot 0.02 rad per metre driven, which odometry misses;
    its turns read 30 % short as well. Driving backwards, the drift turns the other way."""
    calibration = OdometryCalibration()
    random = np.random.RandomState(2)
    for _ in range(100):   # 1 m straight, then a turn, on a real log's sparse scans
        calibration.learn_turn((1.0, 0.0, 0.0), (1.0, 0.0, 0.02 + random.normal(0, 0.005)))
        turn = random.uniform(-0.5, 0.5)
        calibration.learn_turn((0.0, 0.0, 0.7 * turn), (0.0, 0.0, turn))
    assert calibration.turn_scale == pytest.approx(1 / 0.7, rel=0.02)
    assert calibration.heading_drift == pytest.approx(0.02, abs=0.002)
    assert calibration.corrected((0.5, 0.0, 0.0))[2] == pytest.approx(0.01, abs=0.001)
    assert calibration.corrected((-0.5, 0.0, 0.0))[2] == pytest.approx(-0.01, abs=0.001)


def test_a_distance_read_by_a_turn_on_the_spot_teaches_no_scale():
    calibration = OdometryCalibration()
    for _ in range(50):
        calibration.learn_turn((0.0, 0.0, 0.3), (0.0, 0.0, 0.3))
    assert calibration.distance_scale == 1.0 and calibration.heading_drift == 0.0


def test_turns_that_make_no_sense_as_odometry_are_bounded():
    calibration = OdometryCalibration()
    for _ in range(50):
        calibration.learn_turn((0.0, 0.0, 0.1), (0.0, 0.0, 0.5))
    assert calibration.turn_scale == TURN_SCALE_LIMITS[1]
