"""Learning how far the robot goes per metre odometry reads (turtlebot3c_slam.odometry_scale)."""
import numpy as np
import pytest

from turtlebot3c_slam.odometry_scale import SCALE_LIMITS, OdometryScale, firmness_along_heading


def test_a_fresh_scale_trusts_odometry():
    assert OdometryScale().corrected((0.3, 0.05, 0.2)) == (0.3, 0.05, 0.2)


def test_it_learns_how_far_odometry_reads_short_and_corrects_the_next_steps():
    scale = OdometryScale()
    random = np.random.RandomState(1)
    for _ in range(200):   # 10 m of 5 cm steps, read 10 % short, matched to 1 cm
        scale.learn((0.045, 0.0, 0.01), (0.05 + random.normal(0, 0.01), 0.0, 0.01))
    assert scale.corrected((0.09, 0.0, 0.3)) == pytest.approx((0.1, 0.0, 0.3), rel=0.03)


def test_a_backward_step_is_corrected_as_a_forward_one():
    scale = OdometryScale()
    for _ in range(100):
        scale.learn((-0.09, 0.0, 0.0), (-0.1, 0.0, 0.0))
    assert scale.scale == pytest.approx(1 / 0.9, rel=0.02)


def test_matches_that_did_not_pin_the_motion_teach_nothing():
    """Along a featureless corridor the match is the prediction, whatever scale it was made with."""
    scale = OdometryScale()
    for _ in range(100):
        scale.learn((0.09, 0.0, 0.0), (0.1, 0.0, 0.0))
    learnt = scale.scale
    for _ in range(400):   # 36 m, nearly twice the memory
        scale.learn((0.09, 0.0, 0.0), (0.09, 0.0, 0.0), weight=0.0)
    assert scale.scale == pytest.approx(learnt, rel=1e-3)


def test_matches_that_make_no_sense_as_odometry_are_bounded():
    scale = OdometryScale()
    for _ in range(50):
        scale.learn((0.1, 0.0, 0.0), (0.5, 0.0, 0.0))
    assert scale.scale == SCALE_LIMITS[1]


def test_what_was_learnt_fades_with_the_path_so_a_new_floor_is_followed():
    scale = OdometryScale(memory=5.0)
    for _ in range(200):   # 60 m (12 memories) of 0.3 m steps on a floor where odometry reads 10 % short
        scale.learn((0.27, 0.0, 0.0), (0.3, 0.0, 0.0))
    assert scale.scale == pytest.approx(1 / 0.9, rel=0.01)
    for _ in range(200):   # then 60 m where it reads 5 % long
        scale.learn((0.315, 0.0, 0.0), (0.3, 0.0, 0.0))
    assert scale.scale == pytest.approx(1 / 1.05, rel=0.01)


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
