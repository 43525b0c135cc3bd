"""Kill a test's roscore and start a new one on the same port: the fault tests' restarted master."""
import signal
import time

from testkit.ros_harness import descendants, kill_quietly, wait_until


def restart_roscore(master):
    """SIGKILL the roscore (master and rosout) and start a new one on the same port; returns the
    time.monotonic() at which the new master first answered.

    The probe goes too (it was registered with the old master); `master.probe` makes a new one.
    """
    master.probe.close()
    master._probe = None
    for pid in [master.core.pid] + descendants(master.core.pid):  # roslaunch put rosmaster in its own session
        kill_quietly(pid, signal.SIGKILL)
    master.core.wait(10)
    wait_until(lambda: not master.is_up(), 10, "the old master still answers")
    master.core = master.start(["roscore", "-p", str(master.port)], name="roscore-restarted")
    wait_until(master.is_up, 30, "the restarted roscore did not come up", interval=0.01)
    return time.monotonic()
