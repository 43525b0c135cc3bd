"""Mapping when things are missing: no map yet, no master, bad arguments, an unknown SLAM method."""
import subprocess

import pytest

from testkit import ros_harness


def map_saver(env, *args, timeout=60):
    command = ["rosrun", "turtlebot3c_maps", "map_saver"] + [str(a) for a in args]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=timeout)


def test_stopping_mapping_before_any_scan_saves_nothing_and_says_why(ros_master, tmp_path):
    ros_master.launch("turtlebot3c_slam", "turtlebot3c_mapping.launch", "record:=false")
    ros_master.wait_for_node("/turtlebot3_slam_gmapping", timeout=60)
    result = map_saver(ros_master.env, "-f", tmp_path / "new_map", "--wait", "3")
    assert result.returncode == 1
    assert "no map received on /map within 3 s" in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_map_saver_without_a_ros_master_fails_fast_and_clearly(ros_env, tmp_path):
    env = dict(ros_env, ROS_MASTER_URI=f"http://127.0.0.1:{ros_harness.free_port()}")
    result = map_saver(env, "-f", tmp_path / "new_map", "--wait", "2")
    assert result.returncode == 1
    assert "no ROS master at" in result.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, message", [
    (["--occ", "20", "--free", "30"], "free threshold (30) must be below the occupied threshold (20)"),
    (["--occ", "101"], "occupied threshold must be between 1 and 100"),
    (["--wait", "0"], "--wait must be positive"),
])
def test_map_saver_rejects_bad_arguments_before_waiting(ros_env, tmp_path, args, message):
    result = map_saver(ros_env, "-f", tmp_path / "m", *args)
    assert result.returncode == 2
    assert message in result.stderr


def test_unknown_slam_method_stops_the_launch_listing_the_known_ones(ros_master):
    launch = ros_master.launch("turtlebot3c_slam", "turtlebot3c_mapping.launch", "slam_methods:=hector",
                               "record:=false")
    ros_harness.wait_until(lambda: not launch.running(), 60, lambda: "mapping launch still running:\n"
                           + launch.log_text()[-2000:])
    assert "unknown slam_methods 'hector': known methods are gmapping, karto" in launch.log_text()


@pytest.mark.parametrize("parameter, expected", [
    ("_map_update_interval:=0", "slam: parameter ~map_update_interval must be more than 0, got 0"),
    ("_transform_publish_period:=.nan", "slam: parameter ~transform_publish_period must be a finite number, got nan"),
    ("_resolution:=fine", "slam: SLAM parameter resolution must be a finite number, got 'fine'"),
])
def test_a_slam_parameter_the_node_cannot_run_with_stops_it_with_one_line(ros_master, parameter, expected):
    status, log = ros_master.rosrun_refused("turtlebot3c_slam", "slam", parameter)
    assert status == 2
    assert expected in log and "Traceback" not in log


def test_karto_alias_runs_the_same_slam_under_slam_karto(make_master):
    master = make_master()
    master.launch("turtlebot3c_slam", "turtlebot3c_mapping.launch", "slam_methods:=karto", "record:=false")
    master.wait_for_node("/slam_karto", timeout=60)
