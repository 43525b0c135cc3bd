"""snapsim's services behave as snapd's systemd units: chain order, stop sequence, restarts."""
import os
import signal

import pytest

from testkit.ros_harness import wait_until
from testkit.snap_system import SnapSystem, make_demo_project, pid_alive, trace, wait_for_file


@pytest.fixture
def system(tmp_path):
    system = SnapSystem(tmp_path / "root")
    system.snapsim("install", make_demo_project(tmp_path / "demo"), "--dangerous")
    yield system
    system.shutdown()


def common(system, name):
    return system.root / "var" / "snap" / "demo" / "common" / name


def service_trace(system):
    """The trace without the hooks' lines (the configure hook runs while the service starts)."""
    return [line for line in trace(system) if "-hook" not in line]


def test_stop_runs_chain_then_stop_command_then_sigterm_then_post_stop_command(system):
    wait_for_file(common(system, "grandchild.pid"))
    system.snapsim("stop", "demo.svc")
    assert service_trace(system) == [
        "ros1-launch", "chain_one", "chain_two", "command",
        "ros1-launch", "chain_one", "chain_two", "stop-command", "stop-command-saw-main-running",
        "command-got-TERM",
        "ros1-launch", "chain_one", "chain_two", "post-stop-command", "post-stop-saw-main-gone",
    ]


def test_stop_terminates_every_process_of_the_service_even_in_another_session(system):
    grandchild = int(wait_for_file(common(system, "grandchild.pid")) and common(system, "grandchild.pid").read_text())
    assert os.getsid(grandchild) != os.getsid(int(common(system, "main.pid").read_text()))
    system.snapsim("stop", "demo.svc")
    assert not pid_alive(grandchild)
    assert system.status("demo", "svc")["state"] == "inactive"


def test_stop_kills_a_service_ignoring_sigterm_after_stop_timeout(system):
    system.snapsim("start", "demo.stubborn")
    pid = int(wait_for_file(common(system, "stubborn.pid")) and common(system, "stubborn.pid").read_text())
    system.snapsim("stop", "demo.stubborn")
    assert not pid_alive(pid)
    assert "State 'stop-sigterm' timed out. Killing." in system.logs("demo.stubborn")


def test_daemon_restarts_on_failure_until_the_start_rate_limit(system):
    system.snapsim("start", "demo.crasher")
    status = system.wait_state("demo", "crasher", ["failed"])
    assert status["result"] == "start-limit-hit"
    assert trace(system).count("started-3") == 5
    assert "Start request repeated too quickly." in system.logs("demo.crasher")


def test_daemon_is_not_restarted_after_a_clean_exit(system):
    system.snapsim("start", "demo.finisher")
    status = system.wait_state("demo", "finisher", ["inactive"])
    assert status["result"] == "success" and status["starts"] == 1
    assert trace(system).count("started-0") == 1


def test_daemon_killed_by_sigkill_is_restarted(system):
    first = int(wait_for_file(common(system, "main.pid")) and common(system, "main.pid").read_text())
    common(system, "main.pid").unlink()
    os.kill(first, signal.SIGKILL)
    wait_for_file(common(system, "main.pid"))
    status = system.wait_state("demo", "svc", ["active"])
    assert status["restarts"] == 1 and status["main_pid"] != first
    # systemd runs the stop and post-stop commands when the main process dies by itself too
    after_kill = service_trace(system)[4:]
    assert after_kill.index("stop-command") < after_kill.index("post-stop-command") < after_kill.index("command")
    assert "Main process exited, code=killed, signal=SIGKILL" in system.logs("demo.svc")


def service_row(system, service):
    """(Startup, Current) of `snap services`."""
    rows = [line.split() for line in system.snapsim("services", service).stdout.splitlines()]
    assert rows[0] == ["Service", "Startup", "Current", "Notes"]
    return tuple(rows[1][1:3])


def test_start_enable_and_stop_disable_change_startup(system):
    assert service_row(system, "demo.stubborn") == ("disabled", "inactive")
    system.snapsim("start", "--enable", "demo.stubborn")
    assert service_row(system, "demo.stubborn") == ("enabled", "active")
    system.snapsim("stop", "--disable", "demo.stubborn")
    assert service_row(system, "demo.stubborn") == ("disabled", "inactive")


def test_logs_show_the_last_lines_of_a_service(system):
    system.snapsim("stop", "demo.svc")
    lines = system.snapsim("logs", "-n", "2", "demo.svc").stdout.splitlines()
    assert len(lines) == 2
    assert lines[-1].endswith("systemd[1]: snap.demo.svc.service: Stopped Service for snap application demo.svc.")


def test_restart_gives_a_new_main_process(system):
    first = system.wait_state("demo", "svc", ["active"])["main_pid"]
    system.snapsim("restart", "demo.svc")
    wait_until(lambda: system.status("demo", "svc")["main_pid"] not in (None, first), 30, "svc did not restart")
    assert not pid_alive(first)


ORDERED_SNAPCRAFT_YAML = """\
name: ordered
base: core20
version: '1.0'
summary: services with after and before
description: Three services whose start and stop the trace records.
grade: devel
confinement: strict
parts:
  files:
    plugin: dump
    source: local/
    organize:
      '*.sh': usr/bin/
apps:
  alpha:
    command: usr/bin/run.sh alpha
    daemon: simple
    after: [zulu]
  middle:
    command: usr/bin/run.sh middle
    daemon: simple
    after: [alpha]
  zulu:
    command: usr/bin/run.sh zulu
    daemon: simple
    before: [alpha]
"""
ORDERED_RUN = """#!/bin/sh
echo "start $1" >>"$SNAP_COMMON/trace"
trap 'echo "stop $1" >>"$SNAP_COMMON/trace"; exit 0' TERM
sleep 1000 &
wait "$!"
"""


def ordered_project(folder, snapcraft_yaml=ORDERED_SNAPCRAFT_YAML):
    (folder / "snap").mkdir(parents=True)
    (folder / "snap" / "snapcraft.yaml").write_text(snapcraft_yaml)
    (folder / "local").mkdir()
    (folder / "local" / "run.sh").write_text(ORDERED_RUN)
    (folder / "local" / "run.sh").chmod(0o755)
    return folder


def test_services_start_in_their_after_before_order_and_stop_in_reverse(tmp_path):
    system = SnapSystem(tmp_path / "root")
    try:
        system.snapsim("install", ordered_project(tmp_path / "ordered"), "--dangerous")
        assert trace(system, "ordered") == ["start zulu", "start alpha", "start middle"]
        system.snapsim("stop", "ordered")
        assert trace(system, "ordered")[3:] == ["stop middle", "stop alpha", "stop zulu"]
        system.snapsim("restart", "ordered.middle", "ordered.zulu", "ordered.alpha")
        assert trace(system, "ordered")[6:] == ["start zulu", "start alpha", "start middle"]
        system.snapsim("restart", "ordered.zulu")  # ordering only: the others are not restarted
        assert trace(system, "ordered")[9:] == ["stop zulu", "start zulu"]
        listed = [line.split()[0] for line in system.snapsim("services", "ordered").stdout.splitlines()[1:]]
        assert listed == ["ordered.alpha", "ordered.middle", "ordered.zulu"]  # listed by name, as snapd
    finally:
        system.shutdown()


def test_an_after_before_cycle_is_refused_with_a_message(tmp_path):
    cyclic = ORDERED_SNAPCRAFT_YAML.replace("after: [alpha]", "after: [alpha]\n    before: [zulu]")
    system = SnapSystem(tmp_path / "root")
    try:
        done = system.snapsim("install", ordered_project(tmp_path / "ordered", cyclic), "--dangerous", check=False)
        assert done.returncode != 0
        assert "before/after cycle" in done.stderr and "Traceback" not in done.stderr, done.stderr
    finally:
        system.shutdown()
