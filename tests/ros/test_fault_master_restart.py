"""The master-restart decisions (guard and in-process rejoin): when a restart happened, and which
parameters to put back; and asking a master who it is."""
import threading
from xmlrpc.server import SimpleXMLRPCServer

import pytest

from testkit.ros_harness import free_port
from turtlebot3c_common.master_restart import (
    KeptParameters,
    MasterQuery,
    MasterWatch,
    NodeRegistrations,
    flat_parameters,
    master_identity,
    missing_parameters,
    node_registrations,
)


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


def test_a_nodes_namespace_is_kept_leaf_by_leaf_as_the_master_names_parameters():
    namespace = {"map_update_interval": 2.0, "frames": {"base": "base_footprint", "odom": "odom"}, "empty": {}}
    assert flat_parameters("/slam", namespace) == {
        "/slam/map_update_interval": 2.0, "/slam/frames/base": "base_footprint", "/slam/frames/odom": "odom",
        "/slam/empty": {}}
    assert flat_parameters("/answer", 42) == {"/answer": 42}


def test_a_new_master_gets_only_the_node_parameters_it_lacks():
    kept = KeptParameters()
    kept.remember("/amcl", {"min_particles": 500, "laser": {"max_beams": 60}})
    assert kept.missing(["/run_id", "/amcl/min_particles"]) == {"/amcl/laser/max_beams": 60}
    assert kept.missing([]) == {"/amcl/min_particles": 500, "/amcl/laser/max_beams": 60}


def test_no_answer_keeps_the_last_copy_of_the_node_parameters():
    kept = KeptParameters()
    kept.remember("/amcl", {"min_particles": 500})
    kept.remember("/amcl", None)
    assert kept.missing([]) == {"/amcl/min_particles": 500}


class FakeMaster:
    """An XML-RPC server answering getPid and getParam("/run_id") like rosmaster (or not at all)."""

    def __init__(self, pid=4321, run_id="run-1", answers_run_id=True):
        self.server = SimpleXMLRPCServer(("127.0.0.1", free_port()), logRequests=False, allow_none=True)
        self.server.register_function(lambda caller: [1, "", pid], "getPid")
        self.server.register_function(
            lambda caller, name: [1, "", run_id] if answers_run_id and name == "/run_id" else [-1, "no", 0],
            "getParam")
        self.uri = f"http://127.0.0.1:{self.server.server_address[1]}"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def fake_master():
    masters = []

    def make(**kwargs):
        masters.append(FakeMaster(**kwargs))
        return masters[-1]
    yield make
    for master in masters:
        master.close()


def test_a_master_is_known_by_its_run_id_and_pid(fake_master):
    master = fake_master(pid=4321, run_id="run-1")
    assert MasterQuery(master.uri, "/test").identity() == master_identity("run-1", 4321)


def test_a_master_that_answers_only_in_part_has_no_identity(fake_master):
    master = fake_master(answers_run_id=False)
    assert MasterQuery(master.uri, "/test").identity() is None


def test_no_master_at_the_address_has_no_identity():
    assert MasterQuery(f"http://127.0.0.1:{free_port()}", "/test", timeout=1.0).identity() is None


def test_a_nodes_registrations_are_read_from_the_masters_system_state():
    state = [
        [["/rosout", ["/recorder", "/slam"]], ["/map", ["/slam"]]],
        [["/scan", ["/recorder", "/slam"]], ["/tf_static", ["/recorder"]], ["/rosout", ["/rosout"]]],
        [["/recorder/get_loggers", ["/recorder"]], ["/recorder/set_logger_level", ["/recorder"]],
         ["/dynamic_map", ["/slam"]]],
    ]
    types = [["/rosout", "rosgraph_msgs/Log"], ["/map", "nav_msgs/OccupancyGrid"], ["/scan", "sensor_msgs/LaserScan"]]
    service_uris = {"/recorder/get_loggers": "rosrpc://host:1"}  # the other one did not answer
    assert node_registrations("/recorder", "http://host:2/", state, types, service_uris.get) == NodeRegistrations(
        "http://host:2/", publications=[("/rosout", "rosgraph_msgs/Log")],
        subscriptions=[("/scan", "sensor_msgs/LaserScan"), ("/tf_static", "*")],  # nobody publishes it yet
        services=[("/recorder/get_loggers", "rosrpc://host:1")])
    assert node_registrations("/absent", "http://host:3/", state, types, {}.get) == NodeRegistrations("http://host:3/")


class StubMaster:
    """A master's getParamNames and setParam, answering only once `answers` is set."""

    def __init__(self):
        self.params = {}
        self.answers = False

    def call(self, method, *args):
        if not self.answers:
            return None
        if method == "getParamNames":
            return list(self.params)
        if method == "setParam":
            self.params[args[0]] = args[1]
            return 0
        return None


def test_parameters_a_new_master_did_not_take_stay_owed_until_a_later_look_sets_them():
    from turtlebot3c_common.rospy_rejoin import Rejoiner  # rospy: not for the pure-Python unit tests

    master = StubMaster()
    rejoiner = Rejoiner(master, "/amcl", period=0.5)
    rejoiner.parameters.remember("/amcl", {"min_particles": 500})
    rejoiner.restore_parameters()  # a loaded new master that does not answer in time
    assert rejoiner.parameters_owed and master.params == {}
    master.answers = True
    rejoiner.restore_parameters()
    assert not rejoiner.parameters_owed and master.params == {"/amcl/min_particles": 500}
