"""snapsim's install, run, remove and lint: snapd's order, environment and data handling."""
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

from snapsim.supervisor import root_processes
from testkit import ros_harness
from testkit.ros_harness import wait_until
from testkit.snap_system import SNAPSIM, SnapSystem, make_demo_project, trace, wait_for_file


@pytest.fixture
def project(tmp_path):
    return make_demo_project(tmp_path / "demo")


@pytest.fixture
def system(tmp_path):
    system = SnapSystem(tmp_path / "root")
    yield system
    system.shutdown()


def environ(path):
    return dict(line.split("=", 1) for line in Path(path).read_text().splitlines() if "=" in line)


def test_install_runs_install_hook_then_starts_services_then_configure_hook(system, project):
    system.snapsim("install", project, "--dangerous")
    hooks = [line for line in trace(system) if "-hook" in line]
    assert hooks == ["install-hook svc=inactive", "configure-hook svc=active"]
    assert system.config("demo") == {"color": "red"}


def test_install_without_dangerous_is_refused(system, project):
    done = system.snapsim("install", project, check=False)
    assert done.returncode == 1 and "cannot find signatures" in done.stderr
    assert not (system.root / "snap" / "demo").exists()


def test_install_mode_disable_leaves_a_service_disabled_and_inactive(system, project):
    system.snapsim("install", project, "--dangerous")
    rows = {line.split()[0]: line.split()[1:3] for line in system.snapsim("services").stdout.splitlines()[1:]}
    assert rows == {"demo.svc": ["enabled", "active"], "demo.stubborn": ["disabled", "inactive"],
                    "demo.crasher": ["disabled", "inactive"], "demo.finisher": ["disabled", "inactive"]}


def test_daemon_gets_roots_paths_snapd_variables_and_expanded_environment(system, project):
    system.snapsim("install", project, "--dangerous")
    env = environ(wait_for_file(system.root / "var/snap/demo/common/service-env") and
                  system.root / "var/snap/demo/common/service-env")
    mount = system.root / "snap" / "demo" / "x1"
    assert env["SNAP"] == str(mount)
    assert env["SNAP_DATA"] == str(system.root / "var/snap/demo/x1")
    assert env["SNAP_COMMON"] == str(system.root / "var/snap/demo/common")
    assert env["SNAP_USER_DATA"] == env["HOME"] == str(system.root / "root/snap/demo/x1")
    assert env["SNAP_USER_COMMON"] == str(system.root / "root/snap/demo/common")
    assert (env["SNAP_NAME"], env["SNAP_INSTANCE_NAME"], env["SNAP_REVISION"]) == ("demo", "demo", "x1")
    assert env["APP_LEVEL"] == f"{mount}/level/app"  # the app's entry sees the snap-level one
    assert (env["ROS_DISTRO"], env["ROS_VERSION"]) == ("noetic", "1")  # the ros1-noetic extension
    assert env["PATH"].startswith(f"{mount}/usr/sbin:{mount}/usr/bin:")  # snapcraft-runner ran first
    assert (system.root / "root/snap/demo/current").resolve() == system.root / "root/snap/demo/x1"


def test_run_expands_command_arguments_and_drops_empty_ones(system, project):
    system.snapsim("install", project, "--dangerous")
    system.snapsim("run", "demo.tool", "user arg", "*")
    args = (system.root / "var/snap/demo/common/tool-args").read_text().splitlines()
    assert args == ["demo", "fixed", "user arg", "*"]


def test_remove_purge_leaves_nothing_of_the_snap(system, project):
    system.snapsim("install", project, "--dangerous")
    system.snapsim("start", "demo.stubborn")
    running = system.wait_state("demo", "stubborn", ["active"])
    assert {running["main_pid"], running["supervisor"]} <= set(root_processes(system.root))
    system.snapsim("remove", "--purge", "demo")
    leftovers = [path for path in system.root.rglob("*") if "demo" in path.name]
    assert leftovers == []
    assert root_processes(system.root) == []
    assert system.snapsim("services").stdout.splitlines() == ["Service  Startup  Current  Notes"]


def test_remove_without_purge_keeps_a_snapshot_of_the_data(system, project):
    system.snapsim("install", project, "--dangerous")
    done = system.snapsim("remove", "demo")
    assert "snapshot saved" in done.stdout
    snapshots = list((system.root / "var/lib/snapsim/snapshots").iterdir())
    assert len(snapshots) == 1 and (snapshots[0] / "system" / "common" / "trace").exists()
    assert not (system.root / "var/snap/demo").exists()


def test_installing_again_refreshes_keeping_data_and_running_post_refresh(system, project):
    system.snapsim("install", project, "--dangerous")
    (system.root / "var/snap/demo/x1/kept").write_text("data")
    system.snapsim("install", project, "--dangerous")
    assert (system.root / "var/snap/demo/x2/kept").read_text() == "data"
    assert (system.root / "snap/demo/current").resolve().name == "x2"
    assert "post-refresh-hook" in trace(system)
    wait_until(lambda: system.status("demo", "svc")["state"] == "active", 30, "svc not restarted after refresh")


def test_nothing_is_written_outside_the_root(system, project, tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    outside = {"HOME": str(home)}
    system.snapsim("install", project, "--dangerous", env=outside)
    system.snapsim("set", "demo", "color=blue", env=outside)
    system.snapsim("run", "demo.tool", env=outside)
    system.snapsim("remove", "--purge", "demo", env=outside)
    assert list(home.iterdir()) == []
    assert sorted(path.name for path in tmp_path.iterdir()) == ["demo", "home", "root"]


def virtualenv_seeing_our_packages(folder):
    """A virtualenv other than the project's, whose python3 imports what ours does (PyYAML..., snapsim)."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True, timeout=120)
    [site_packages] = folder.glob("lib/python3*/site-packages")
    ours = [path for path in sys.path if path.endswith(("site-packages", "dist-packages"))] + [str(ros_harness.REPO)]
    (site_packages / "ours.pth").write_text("".join(f"{path}\n" for path in ours))
    return folder


def test_services_a_hook_restarts_keep_the_virtualenv_snapsim_runs_in(system, project, tmp_path):
    venv = virtualenv_seeing_our_packages(tmp_path / "other-venv")
    system.snapsim_program = [str(venv / "bin" / "python3"), "-m", "snapsim"]  # snapsim run by its python3
    started_by_it = {"PATH": f"{venv / 'bin'}:/usr/bin:/bin"}
    system.snapsim("install", project, "--dangerous", env=started_by_it)
    first = system.wait_state("demo", "svc", ["active"])["main_pid"]
    main_pid_file = system.root / "var/snap/demo/common/main.pid"

    system.snapsim("set", "demo", "restart-svc=true", env=started_by_it)  # configure: snapctl restart demo.svc

    # service.sh writes main.pid after service-env: a new pid there means the restarted service's env is written
    wait_until(lambda: main_pid_file.read_text().strip() not in ("", str(first)), 30, "svc never restarted")
    path = environ(system.root / "var/snap/demo/common/service-env")["PATH"].split(":")
    assert str(venv / "bin") in path
    assert str(ros_harness.VENV / "bin") not in path


def test_snapsim_needs_a_root(tmp_path):
    env = {key: value for key, value in os.environ.items() if key != "SNAPSIM_ROOT"}
    done = subprocess.run([str(SNAPSIM), "services"], env=env, capture_output=True, text=True)
    assert done.returncode == 2 and "--root" in done.stderr


def test_lint_accepts_the_demo_and_names_each_problem_of_a_broken_snap(system, project):
    system.snapsim("install", project, "--dangerous")
    assert system.snapsim("lint", "demo").stdout == ""
    mount = system.root / "snap" / "demo" / "x1"
    meta = yaml.safe_load((mount / "meta" / "snap.yaml").read_text())
    meta["apps"]["tool"]["stop-timeout"] = "10s"
    meta["hooks"]["not-a-hook"] = {}
    (mount / "meta" / "snap.yaml").write_text(yaml.safe_dump(meta))
    (mount / "usr" / "bin" / "chain_two.sh").chmod(0o644)
    (mount / "usr" / "bin" / "outside").symlink_to("/etc/passwd")
    problems = system.snapsim("lint", "demo", check=False).stdout
    assert "app tool: stop-timeout is only for daemons" in problems
    assert "hook not-a-hook: unknown hook name" in problems
    assert "app svc: command-chain: usr/bin/chain_two.sh is not executable" in problems
    assert "usr/bin/outside: symlink to /etc/passwd points outside the snap" in problems


def test_connections_auto_connect_network_and_connect_joystick_on_request(system, project):
    system.snapsim("install", project, "--dangerous")

    def rows():
        lines = system.snapsim("connections", "demo").stdout.splitlines()[1:]
        return {line.split()[1]: line.split()[2] for line in lines}
    assert rows() == {"demo:joystick": "-", "demo:network": ":network"}
    is_connected = 'snapctl is-connected joystick && echo yes || echo no'
    assert system.snapsim("run", "--shell", "demo.tool", "-c", is_connected).stdout.strip() == "no"
    system.snapsim("connect", "demo:joystick")
    assert rows()["demo:joystick"] == ":joystick"
    assert system.snapsim("run", "--shell", "demo.tool", "-c", is_connected).stdout.strip() == "yes"


def test_logs_follow_prints_new_lines_as_they_come(system, project):
    system.snapsim("install", project, "--dangerous")
    follower = subprocess.Popen([str(SNAPSIM), "--root", str(system.root), "logs", "-f", "-n", "1", "demo.svc"],
                                env=system.env, stdout=subprocess.PIPE, text=True)
    watchdog = threading.Timer(60, follower.kill)
    watchdog.start()
    try:
        lines = iter(follower.stdout.readline, "")
        next(lines)  # the last line so far: the follower has read the journal, what comes next is new
        system.snapsim("stop", "demo.svc")
        assert any("Stopped Service for snap application demo.svc." in line for line in lines)
    finally:
        watchdog.cancel()
        follower.kill()
        follower.wait()


def test_install_whose_configure_hook_fails_is_undone(system, project):
    hook = project / "snap" / "hooks" / "install"
    hook.write_text(hook.read_text().replace("color=red", "color=purple"))
    done = system.snapsim("install", project, "--dangerous", check=False)
    assert done.returncode == 1 and "color: 'purple' is not allowed" in done.stderr
    assert [path for path in system.root.rglob("*") if "demo" in path.name] == []
    assert root_processes(system.root) == []
