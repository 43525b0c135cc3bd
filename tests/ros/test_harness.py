"""The test plumbing itself: masters on free ports, waits, and no stray processes."""

import pytest

from testkit import ros_harness


def test_master_runs_on_a_free_port_that_is_not_the_default(ros_master):
    assert ros_master.port != 11311
    assert ros_master.is_up()


def test_probe_round_trips_a_message_through_the_master(ros_master):
    probe = ros_master.probe
    probe.subscribe("/harness_echo", "std_msgs/String")
    ros_master.wait_for_publisher("/rosout")
    probe.publish("/harness_echo", "std_msgs/String", {"data": "hello"})
    message = probe.wait_for_message("/harness_echo", "std_msgs/String", start=0, timeout=10)
    assert message == {"data": "hello"}


def test_wait_until_fails_with_the_message_after_the_deadline():
    with pytest.raises(TimeoutError, match="never true"):
        ros_harness.wait_until(lambda: False, 0.2, "never true")


def test_stopping_a_master_kills_roslaunch_and_its_nodes(make_master):
    master = make_master()
    master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    master.wait_for_node("/mux")
    master.wait_for_node("/velocity_watchdog")
    family = [pid for process in master.processes for pid in [process.pid] + ros_harness.descendants(process.pid)]
    assert len(family) >= 5  # roscore, rosmaster, rosout, roslaunch, mux, velocity_watchdog

    master.shutdown()

    alive = [pid for pid in family if _alive(pid)]
    assert alive == []


def test_a_process_that_ignores_sigint_and_sigterm_is_still_killed(make_master):
    master = make_master()
    stubborn = master.start([ros_harness.python(), "-c", (
        "import signal, time\n"
        "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
        "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
        "time.sleep(600)\n")], name="stubborn")
    master.shutdown()
    assert not _alive(stubborn.pid)


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_failed_launch_logs_are_readable(ros_master):
    broken = ros_master.launch("turtlebot3c_teleop", "no_such_file.launch")
    broken.wait(30)
    assert broken.popen.returncode != 0
    assert "no_such_file.launch" in broken.log_text()
    assert "no_such_file.launch" in ros_master.logs()
