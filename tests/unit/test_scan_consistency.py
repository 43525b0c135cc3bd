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


def test_icp_finds_a_scan_laid_over_itself_from_a_start_that_is_off(log):
    twice = log._replace(stamps=log.stamps[:2], ranges=log.ranges[[5, 5]], reference=log.reference[:2])
    pose, information = scan_consistency.match(scan_consistency.ScanSet(twice), 0, 1, (0.06, -0.04, 0.03))
    assert pose == pytest.approx((0.0, 0.0, 0.0), abs=2e-3)
    assert np.all(np.linalg.eigvalsh(information) > 0)


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
