"""Which steps make a trajectory's error against the reference, and whether the scans side with
them (benchmarks/gap_attribution.py)."""
import numpy as np
import pytest

from benchmarks import gap_attribution, scan_consistency
from testkit.real_data import load_log
from turtlebot3c_common.se2 import compose, moved_from
from turtlebot3c_sim.evaluation import relative_pose_errors


@pytest.fixture(scope="module")
def log():
    return load_log("freiburg-101", 40)


def test_every_step_taken_as_the_reference_takes_it_is_the_reference_in_another_frame(log):
    shaken = log.reference + np.random.RandomState(1).normal(0.0, 1.0, log.reference.shape) * (0.05, 0.05, 0.02)
    mended = gap_attribution.with_reference_steps(shaken, log.reference, range(1, len(log.reference)))
    assert relative_pose_errors(shaken, log.reference, log.travel()).translation > 0.05
    assert relative_pose_errors(mended, log.reference, log.travel()).translation < 1e-9


def test_a_step_the_scans_pin_elsewhere_is_the_mappers_to_take(log):
    wrong = moved_from(log.reference, 20, compose(tuple(log.reference[20]), (0.0, 0.2, 0.05)))
    gaps = gap_attribution.largest_gaps(scan_consistency.ScanSet(log), wrong, log.reference, log.travel())
    largest = gaps[0]
    assert largest.scan == 20 and largest.sides_with == "reference"
    assert largest.gain == pytest.approx(relative_pose_errors(wrong, log.reference, log.travel()).translation)


def test_where_the_reference_misplaces_a_scan_the_scans_side_with_the_trajectory_that_does_not():
    """csail's reference turns scan 364 about 20 degrees from where the scans around it put it
    (scan_consistency.reseated moves it back)."""
    log = load_log("csail").part(slice(356, 369))
    scans = scan_consistency.ScanSet(log)
    by_scans = scan_consistency.reseated(scans, log.reference)
    gaps = {gap.scan: gap for gap in gap_attribution.largest_gaps(scans, by_scans, log.reference, log.travel())}
    assert gaps[8].sides_with == "trajectory"
    assert gaps[8].fit_trajectory > 2 * gaps[8].fit_reference


def test_a_scan_that_overlaps_none_before_it_leaves_the_scans_no_word():
    assert gap_attribution.sides_with(0, 0) == "neither"
    assert gap_attribution.sides_with(100, 105) == "neither"
    assert gap_attribution.sides_with(0, 50) == "reference"
