"""The benchmark's reference-free yardsticks (benchmarks/scan_consistency.py) on real scans."""
import numpy as np
import pytest

from benchmarks import scan_consistency
from testkit.real_data import load_log
from turtlebot3c_common.se2 import compose, relative


@pytest.fixture(scope="module")
def log():
    return load_log("freiburg-101", 40)


@pytest.fixture(scope="module")
def scans(log):
    return scan_consistency.ScanSet(log)


def test_a_trajectory_that_strays_from_the_scans_is_less_consistent(log, scans):
    noise = np.random.RandomState(1).normal(0.0, 1.0, log.reference.shape) * (0.05, 0.05, 0.01)
    shaken = log.reference + noise
    assert scan_consistency.consistency(scans, shaken) > 1.5 * scan_consistency.consistency(scans, log.reference)


def test_a_closure_is_judged_by_the_scans_it_joins(log, scans):
    i, j = 10, 12
    truth = relative(tuple(log.reference[i]), tuple(log.reference[j]))
    off = compose(truth, (0.6, 0.0, 0.0))
    assert scan_consistency.false_by_scans(scans, [(i, j, truth)], log.reference) == 0
    assert scan_consistency.false_by_scans(scans, [(i, j, truth), (i, j, off)], log.reference) == 1


def test_a_closure_the_scans_support_is_not_false_where_the_reference_is_wrong():
    """csail's reference turns 11 degrees between scans 396 and 397 that the scans do not: ICP of
    396 and 397 fits 94 % of the points, the reference's pose 40 %. A closure from scan 11 to 399
    that follows the scans must not count as false because ICP started from the reference's pose
    stops in a minimum that fits half as well."""
    log = load_log("csail")
    scans = scan_consistency.ScanSet(log)
    reference = relative(tuple(log.reference[11]), tuple(log.reference[399]))
    by_scans = compose(reference, (0.0, 0.0, np.radians(11.0)))
    aligned = scan_consistency.best_alignment(scans, 11, 399, [by_scans])
    assert scan_consistency.false_by_scans(scans, [(11, 399, aligned)], log.reference) == 0
    assert scan_consistency.false_by_scans(scans, [(11, 399, compose(aligned, (0.5, 0.0, 0.0)))], log.reference) == 1


def test_a_closure_that_fits_better_than_where_icp_slides_is_not_false():
    """infinite-corridor, severe odometry, on core20's numpy: the SLAM closed scan 679 to 1894 at a
    pose that lays 130 points of 1894 on 679's lines. The reference's pose lays 115 and is 0.15 m
    away (within the tolerance); ICP from either slides along the corridor to one that lays 110,
    0.6 m away. The scans support the closure."""
    log = load_log("infinite-corridor").part([679, 1894])
    scans = scan_consistency.ScanSet(log)
    claimed = (0.419, 0.387, -0.122)
    assert scan_consistency.false_by_scans(scans, [(0, 1, claimed)], log.reference) == 0
    assert scan_consistency.false_by_scans(scans, [(0, 1, compose(claimed, (0.0, 0.5, 0.0)))], log.reference) == 1


def moved_scans(log, reseated):
    return [i for i in range(len(log.reference)) if not np.allclose(reseated[i], log.reference[i, :3])]


def test_a_reference_its_scans_agree_with_is_left_as_it_is(log, scans):
    assert moved_scans(log, scan_consistency.reseated(scans, log.reference)) == []


def test_a_scan_the_reference_turns_beyond_the_refinements_reach_is_put_where_its_scans_fit():
    """csail's reference turns scan 364 about 20 degrees from where scans 363 and 365 put it: no
    refinement from the reference mends that (it takes no match 0.1 rad from where it starts)."""
    log = load_log("csail").part(slice(360, 369))
    scans = scan_consistency.ScanSet(log)
    reseated = scan_consistency.reseated(scans, log.reference)
    assert moved_scans(log, reseated) == [4]
    turned = np.degrees(relative(tuple(log.reference[4]), tuple(reseated[4]))[2])
    assert 15.0 < abs(turned) < 25.0
    for neighbour in (3, 5):
        on_lines = [scans.clouds[neighbour].points_on_lines(scans.clouds[4].points,
                                                            relative(tuple(poses[neighbour]), tuple(poses[4])))
                    for poses in (log.reference, reseated)]
        assert on_lines[1] > 2 * on_lines[0]


def test_scans_the_reference_misplaces_together_are_moved_together():
    """csail's reference turns scans 397-399 about 11 degrees that the scans do not, and 400 back."""
    log = load_log("csail").part(slice(394, 403))
    reseated = scan_consistency.reseated(scan_consistency.ScanSet(log), log.reference)
    assert moved_scans(log, reseated) == [3, 4, 5]
    turns = [np.degrees(relative(tuple(log.reference[i]), tuple(reseated[i]))[2]) for i in (3, 4, 5)]
    assert all(8.0 < abs(turn) < 14.0 for turn in turns)
    assert max(turns) - min(turns) < 1.0
