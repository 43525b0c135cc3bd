"""AMCL on real laser data: a Radish log (a SICK LMS, 180 degrees, scans about 1 m apart) with the
worst odometry error model, started 1 m / 0.5 rad off, on the map of the log's own scans. The
parameters are the benchmark's one set for every log (testkit.real_data.AMCL_PARAMS)."""
import numpy as np
import pytest

from testkit.real_data import (
    AMCL_BOUND,
    after_convergence,
    amcl_figures,
    amcl_floor,
    amcl_floor_held_out,
    converged_scan,
    even_scans,
    load_log,
    odd_scans,
    reference_map,
    run_amcl,
    run_amcl_with,
)
from turtlebot3c_sim.odometry_error import SEVERITIES, noisy_odometry


@pytest.fixture(scope="module")
def seattle():
    log = load_log("seattle", 150)  # 150 scans, 120 m of a lab's corridors and rooms
    return log, reference_map(log)


def test_amcl_converges_from_1_m_and_half_a_radian_off_and_tracks_within_the_issue_targets(seattle):
    log, occupancy_map = seattle
    run = run_amcl(log, "severe", seed=1, occupancy_map=occupancy_map)
    assert run.converged and run.converged_at <= 10
    assert run.translation <= 0.05 and run.rotation <= 1.5   # issue #21: 0.05 m / 1.5 deg mean
    assert run.held >= 0.9
    assert run.relocalizations == 0


def test_a_filter_started_at_the_truth_is_not_thrown_off_by_the_odometry(seattle):
    log, occupancy_map = seattle
    run = run_amcl(log.head(60), "severe", seed=2, occupancy_map=occupancy_map, offset=(0.0, 0.0))
    assert run.converged_at == 0
    assert run.translation <= 0.05 and run.translation_errors.max() < 0.5


def test_on_a_5_hz_log_the_pose_between_filter_updates_stays_within_the_issue_targets():
    # freiburg-079: 360 beams, a scan every 0.1 m, so the filter does not update at every scan and
    # between updates the pose is the odometry's (0.3 rad wrong per radian turned). With amcl.yaml's
    # update_min_a (0.2 rad) it held 93 % and converged at scan 21 (804 judged over scans). Scan 13
    # (2.6 s) since the motion model's short moves (odom_short_move), scan 2 before: this seed's
    # first metre, 0.15 m off where it was 0.05; filter seeds 11-13 converge at scan 0 with and without.
    log = load_log("freiburg-079", 900)
    run = run_amcl(log, "severe", seed=1, occupancy_map=reference_map(log))
    assert run.converged and run.converged_at <= 15
    assert run.translation <= 0.05 and run.rotation <= 1.5
    assert run.held >= 0.95


@pytest.mark.parametrize("seed, held_out", [(1, False), (3, False), (2, True)])
def test_a_turn_on_the_spot_among_people_does_not_throw_the_filter_metres_off(seed, held_out):
    # fhw, scans 55-65: the robot turns on the spot with something close all around it (median
    # range 0.8-0.9 m; at the reference pose 9-36 % of the beams end on a wall). Seed 1: while
    # the beams that end short counted as not fitting, the filter took itself for lost at scan
    # 62, spread its cloud along the path and settled 3.0 m off (now at most 0.69 m, at scans
    # 60-62). Seed 3: while those beams counted in the weighting, scan 59 turned the cloud 84
    # degrees, and it was lost until scan 120, up to 49 m off (now at most 0.32 m). Seed 2, on
    # the map of the even scans: scan 59 fits it better turned 110 degrees than at the truth, and
    # the filter turned and was lost for the rest of the log, 14 m off on average, until such a
    # scan no longer weighed (poor_fit_max_jump).
    log = load_log("fhw")
    occupancy_map = reference_map(even_scans(log) if held_out else log)
    run = run_amcl(log.head(130), "severe", seed=seed, occupancy_map=occupancy_map)
    assert run.converged_at == 0
    assert run.translation_errors[55:].max() < 1.0


def test_a_cloud_turned_onto_a_wrong_heading_in_the_crowd_is_found_again_from_where_it_last_tracked():
    # fhw, severe, odometry seed 1, filter seed 110, on the reference map: in the turn among
    # people scan 59 splits the cloud, which settles 86-94 degrees off. Scan 61 fits there,
    # between two that do not, and while one fitting scan anchored the local spread, the cloud
    # spread around that heading when the filter took itself for lost (scan 69), and never found
    # the robot again (4.1 m off on average over the log). The last estimate that tracked is
    # scan 58's, 0.2 m off.
    whole = load_log("fhw")
    log = whole.head(130)
    odometry = noisy_odometry(log.reference, SEVERITIES["severe"], 1)
    run = run_amcl_with(log, odometry, 110, occupancy_map=reference_map(whole))
    assert run.translation_errors[60:69].min() > 0.4   # the turn took the cloud off
    assert run.translation_errors[75:].max() < 0.3


@pytest.fixture(scope="module")
def corridor_with_slips():
    """infinite-corridor's scans 1740-1830, their odometry (severe, seed 2) and the map around."""
    log = load_log("infinite-corridor")
    odometry = noisy_odometry(log.reference, SEVERITIES["severe"], 2)
    corridor = slice(1740, 1830)
    return log.part(corridor), odometry[corridor], reference_map(log.part(slice(1700, 1900)))


@pytest.mark.parametrize("filter_seed", [2, 3])
def test_a_cloud_that_slips_behind_along_a_corridor_catches_up_when_the_corridor_ends(corridor_with_slips, filter_seed):
    # infinite-corridor, severe, odometry seed 2: along the corridor (scans 1770-1795) the wheels
    # slip twice (steps of 1.12 and 1.00 m read as 0.60 and 0.34) and the odometry reads 10 %
    # short. The walls fit all along the corridor, so nothing holds the cloud to the robot there
    # (it falls 1-2 m behind). With no particle taking a step as a slip, none was near the robot
    # when the corridor ended: these filter seeds stayed 1.2 m and 25 m off.
    log, odometry, occupancy_map = corridor_with_slips
    run = run_amcl_with(log, odometry, filter_seed, occupancy_map=occupancy_map, offset=(0.0, 0.0))
    assert run.translation_errors[:30].max() < 0.3   # before the slips
    assert run.translation_errors[60:].max() < 0.2   # from scan 1800, past the corridor's end


def test_convergence_is_the_first_scan_within_the_bound_that_most_of_the_next_scans_keep():
    t, r = AMCL_BOUND
    good, off = (t / 2, r / 2), (t * 3, r / 2)
    errors = [off] * 5 + [good] * 20
    assert converged_scan(*np.array(errors).T) == 5
    # A scan or a few off later (the reference off, a slipping wheel) do not undo it ...
    errors = [off] * 5 + [good] * 10 + [off] * 3 + [good] * 10
    assert converged_scan(*np.array(errors).T) == 5
    # ... and neither does losing the robot later: the lost scans count against the filter.
    errors = [off] * 5 + [good] * 10 + [off] * 8 + [good] * 12
    assert converged_scan(*np.array(errors).T) == 5
    # Passing through the bound on the way is not converging.
    errors = [off] * 5 + [good] * 2 + [off] * 10 + [good] * 15
    assert converged_scan(*np.array(errors).T) == 17
    # Heading counts as much as position; never within the bound, or not for long enough: None.
    errors = [(t / 2, r * 2)] * 25
    assert converged_scan(*np.array(errors).T) is None
    assert converged_scan(*np.array([off] * 20 + [good] * 5).T) is None


def test_a_loss_after_convergence_counts_in_the_figures():
    t, r = AMCL_BOUND
    errors = np.array([(t / 2, r / 2)] * 20 + [(1.0, r / 2)] * 10 + [(t / 2, r / 2)] * 20)
    start = converged_scan(*errors.T)
    translation, _, held = after_convergence(*errors.T, start)
    assert start == 0
    assert translation == pytest.approx(np.mean(errors[:, 0]))
    assert held == pytest.approx(0.8)


def test_staying_is_judged_over_metres_of_travel_not_over_scans():
    t, r = AMCL_BOUND
    good, off = (t / 2, r / 2), (t / 2, r * 3)
    # A scan every 0.1 m (freiburg-079, 5 Hz): ten scans within are a metre, two seconds, not the
    # ten metres they are on a log with a scan every metre; they are not staying ...
    errors = [off] * 5 + [good] * 10 + [off] * 90 + [good] * 150
    travel = 0.1 * np.arange(len(errors))
    assert converged_scan(*np.array(errors).T, travel) == 105
    # ... a hundred (ten metres) are.
    errors = [off] * 5 + [good] * 100 + [off] * 80 + [good] * 150
    travel = 0.1 * np.arange(len(errors))
    assert converged_scan(*np.array(errors).T, travel) == 5
    # Without hold metres of travel after it, no scan counts.
    assert converged_scan(*np.array([good] * 50).T, 0.1 * np.arange(50)) is None


def test_on_a_map_without_the_scans_it_is_judged_on_amcl_still_meets_the_issue_targets():
    # A robot localises on a map made earlier, from other scans: here the map is drawn from the
    # even scans alone and the figures count the odd ones.
    figures = amcl_figures("seattle", "severe", seed=1, scans=150, held_out=True)
    assert figures.converged and figures.converged_at <= 10
    assert figures.translation <= 0.05 and figures.rotation <= 1.5
    assert figures.held >= 0.9
    # ... and is about as close to the reference as the scans' own best fits on that map.
    assert figures.translation <= 1.2 * amcl_floor_held_out("seattle", 150).translation


def test_the_amcl_floor_is_how_far_the_reference_is_from_where_the_scans_fit_the_map(seattle):
    log, _ = seattle
    odd = odd_scans(log)
    occupancy_map = reference_map(even_scans(log))
    assert amcl_floor(log, occupancy_map, odd).translation < 0.04
    # The odd scans' reference poses 0.15 m off to the side, a degree turned: the scans still
    # fit where they were taken.
    shifted = log.reference.copy()
    shifted[odd] += (0.0, 0.15, np.radians(1.0))
    floor = amcl_floor(log._replace(reference=shifted), occupancy_map, odd)
    assert floor.translation == pytest.approx(0.15, abs=0.03)
    assert floor.rotation == pytest.approx(1.0, abs=0.3)


def test_a_corridor_whose_walls_only_some_rays_hit_keeps_them_in_the_map_and_amcl_on_them():
    # aces at severe, seed 1: at scan 207 odometry reads a 0.98 m step as 1.77 m, in a corridor
    # whose walls the even scans hit with some rays and pass with others. A map that called such
    # walls unknown left AMCL 1.4-1.9 m off for ten scans (207-216); MRPT's pf-localization held
    # on the same scans. The slip still carries the pose off at scan 207 itself, but the next
    # scans' walls bring it back: within 0.2 m from scan 209 on, and never 0.5 m off again.
    log = load_log("aces")
    run = run_amcl(log, "severe", seed=1, occupancy_map=reference_map(even_scans(log)), judged=odd_scans(log))
    assert run.converged_at is not None and run.converged_at <= 5
    assert run.translation_errors[209:217].max() < 0.2
    assert run.translation_errors[209:].max() < 0.5
