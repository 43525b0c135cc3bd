"""The master-restart guard's decisions: when a restart happened, and which parameters to put back."""
from turtlebot3c_bringup.master_restart import MasterWatch, master_identity, missing_parameters


def test_the_first_master_seen_is_not_a_restart():
    assert not MasterWatch().observe(master_identity("run-1", 100))


def test_a_master_that_stops_answering_and_comes_back_the_same_is_not_a_restart():
    watch = MasterWatch()
    watch.observe(master_identity("run-1", 100))
    assert not watch.observe(None)
    assert not watch.observe(master_identity("run-1", 100))


def test_a_new_run_id_or_pid_after_an_outage_is_a_restart_reported_once():
    watch = MasterWatch()
    watch.observe(master_identity("run-1", 100))
    watch.observe(None)
    assert watch.observe(master_identity("run-2", 100))
    assert not watch.observe(master_identity("run-2", 100))
    assert watch.observe(master_identity("run-2", 200))


def test_only_parameters_the_new_master_lacks_are_restored():
    kept = {"/robot_description": "<robot/>", "/mux": {"initial_topic": "nav_vel"}}
    assert missing_parameters(kept, ["/mux"]) == {"/robot_description": "<robot/>"}
    assert missing_parameters(kept, []) == kept
