"""Fixtures shared by every test: the built workspace's environment and a roscore per module."""
import pytest

from testkit import ros_harness


@pytest.fixture(scope="session")
def ros_env():
    """Environment of the installed workspace (tools/build's install spaces)."""
    return ros_harness.install_space_environment()


@pytest.fixture(scope="module")
def ros_master(ros_env, request):
    """A real roscore on a free port, private to this test module."""
    workdir = ros_harness.new_workdir(request.module.__name__)
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
