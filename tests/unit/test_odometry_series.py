"""Odometry read from a bag (bag_inputs.OdometrySeries): interpolated as tf does, with samples that
are not numbers left out and jumps no robot makes taken as no motion."""
import math

import pytest

from turtlebot3c_common.bag_inputs import OdometrySeries


def driving(seconds, speed=0.2, rate=10.0):
    """Stamps and poses of a robot driving along x at `speed` (m/s), sampled at `rate` (Hz)."""
    stamps = [index / rate for index in range(int(seconds * rate) + 1)]
    return stamps, [(speed * stamp, 0.0, 0.0) for stamp in stamps]


def test_a_sample_far_off_the_path_that_the_odometry_comes_back_to_is_left_out():
    stamps, poses = driving(4.0)
    poses[20] = (1e12, -3e11, 2.0)  # a glitch at 2 s
    series = OdometrySeries(stamps, poses)
    assert series.off_path == 1 and series.jumps == 0 and len(series) == len(stamps) - 1
    assert series.at(2.0) == pytest.approx((0.4, 0.0, 0.0))
    assert series.poses == [pose for index, pose in enumerate(poses) if index != 20]
    assert series.repairs() == " (1 sample off the path left out)"


def test_odometry_that_starts_again_from_zero_continues_from_where_it_was():
    stamps, poses = driving(4.0, speed=1.0)
    poses[21:] = [(x - poses[21][0], y, yaw) for x, y, yaw in poses[21:]]  # a board reset at 2.1 s
    series = OdometrySeries(stamps, poses)
    assert series.jumps == 1
    assert series.at(4.0) == pytest.approx((4.0 - 0.1, 0.0, 0.0), abs=1e-9)
    assert series.repairs() == " (1 jump taken as no motion)"


def test_a_jump_in_the_last_second_is_taken_as_a_reset_too():
    stamps, poses = driving(4.0, speed=1.0)
    poses[37:] = [(x + 50.0, y, yaw) for x, y, yaw in poses[37:]]
    series = OdometrySeries(stamps, poses)
    assert series.jumps == 1 and series.off_path == 0
    assert series.at(4.0) == pytest.approx((4.0 - 0.1, 0.0, 0.0), abs=1e-9)


def test_samples_that_are_not_numbers_are_left_out():
    stamps, poses = driving(2.0)
    poses[5], poses[6] = (math.nan, 0.0, 0.0), (0.0, 0.0, math.inf)
    series = OdometrySeries(stamps, poses)
    assert series.not_numbers == 2 and series.jumps == 0 and len(series) == len(stamps) - 2
    assert series.at(0.55) == pytest.approx((0.11, 0.0, 0.0))
    assert series.repairs() == " (2 samples that are not a number left out)"


def test_fast_but_real_steps_are_not_jumps_and_are_kept_as_read():
    stamps, poses = driving(20.0, speed=3.0, rate=1.0)  # a 1 Hz log of a robot going 3 m/s
    turning = [(x, 0.0, math.remainder(0.9 * index, 2 * math.pi)) for index, (x, _, _) in enumerate(poses)]
    series = OdometrySeries(stamps, turning)
    assert series.jumps == 0 and series.repairs() == ""
    assert series.poses == turning
