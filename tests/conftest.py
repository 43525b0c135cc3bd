"""Fixtures shared by every test: the built workspace's environment and a roscore per module; and the
split of the suite into the tests that need a ROS master and those that need none (`--lane`)."""
from pathlib import Path

import pytest

from testkit import ros_harness

# A test needs a ROS master when it asks for one of these fixtures, is marked `needs_master` (one
# that starts its master by itself), or tests the snap through snapsim (the snap's own roscore app).
MASTER_FIXTURES = {"ros_master", "make_master"}
SNAP_TESTS = Path(__file__).resolve().parent / "snap"
# Runs the maps app as uid 65534, who cannot reach an interpreter under /root (pyenv's Python 3.8):
# it runs with the tests that need a master, on this machine's Python, rather than be skipped.
AS_ANOTHER_USER = {"tests/ros/test_maps_store.py::test_command_line_lists_as_json_and_refuses_changes_without_root"}


def pytest_addoption(parser):
    parser.addoption(
        "--lane", choices=("all", "core20", "master"), default="all",
        help="core20: only the tests that need no ROS master (tools/core20-lane runs them on Python 3.8); "
             "master: only those that need one; all (default): every test")


def needs_master(item):
    return bool(MASTER_FIXTURES & set(getattr(item, "fixturenames", ()))
                or item.get_closest_marker("needs_master")
                or SNAP_TESTS in Path(str(item.fspath)).parents)


def pytest_collection_modifyitems(config, items):
    lane = config.getoption("--lane")
    if lane == "all":
        return
    keep = [item for item in items if runs_on_this_python(item) == (lane == "master")]
    config.hook.pytest_deselected(items=[item for item in items if item not in keep])
    items[:] = keep


def runs_on_this_python(item):
    """Whether the test stays out of the core20 lane: it needs a master, or runs as another user."""
    return needs_master(item) or item.nodeid in AS_ANOTHER_USER


@pytest.fixture(scope="session")
def ros_env():
    """Environment of the installed workspace (tools/build's install spaces)."""
    return ros_harness.install_space_environment()


@pytest.fixture(scope="module")
def ros_master(ros_env, request, tmp_path_factory):
    """A real roscore on a free port, private to this test module; its logs stay in pytest's
    temporary folder (the last three runs' are kept)."""
    workdir = tmp_path_factory.mktemp(request.module.__name__.rpartition(".")[2])
    master = ros_harness.RosMaster(ros_env, workdir)
    request.config.stash.setdefault(_MASTERS, {})[request.module.__name__] = master
    yield master
    master.shutdown()


_MASTERS = pytest.StashKey()


@pytest.fixture
def make_master(ros_env, tmp_path):
    """Start extra masters inside one test; all are shut down when it ends."""
    masters = []

    def make():
        master = ros_harness.RosMaster(ros_env, tmp_path / f"master{len(masters)}")
        masters.append(master)
        return master
    yield make
    for master in masters:
        master.shutdown()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if report.failed and "ros_master" in getattr(item, "fixturenames", ()):
        master = item.config.stash.get(_MASTERS, {}).get(item.module.__name__)
        if master is not None:
            report.sections.append(("ROS process logs", master.logs()))
    return report


def pytest_sessionfinish(session, exitstatus):
    leftovers = ros_harness.kill_marked_processes()
    if leftovers:
        session.config.stash[_LEFTOVERS] = leftovers
        session.exitstatus = 1


_LEFTOVERS = pytest.StashKey()


def pytest_terminal_summary(terminalreporter, config):
    leftovers = config.stash.get(_LEFTOVERS, None)
    if leftovers:
        terminalreporter.write_line(
            f"ERROR: {len(leftovers)} processes started by tests outlived the suite (killed): {leftovers}", red=True)
