#!/usr/bin/env python3
"""roslaunch that joins the ROS master and never starts one: the roscore app runs the master.

    roslaunch_joining.py [roslaunch arguments...]

`roslaunch --wait` waits for a master only once, as it starts; if the master dies before
roslaunch gets to it (a crash, the roscore app restarted), roslaunch would start a master of
its own, which then fights the roscore app's for the port. Here it stops instead, with one
line naming the URI; the daemon's restart runs wait_for_master.sh again.

A launch must also start against one master from its parameters to its last node. If the
master restarts in between, the parameters went to the old one and the nodes started since
read none from the new one (defaults, or robot_state_publisher without /robot_description);
the master-restart guard, itself just started, takes the new master for the first it has seen
and repairs nothing. So this launch notes the master (its /run_id and pid) as it loads the
parameters, waits until every node of the launch is registered and then SETTLE s more (the
nodes read their parameters, the guard takes its first look), and stops with status 1 if the
master is another one by then: the daemon starts again against the master that runs. A
restart after that is a crash the guards and the in-process rejoin repair. Nor does it ever
set /run_id itself (roslaunch does on a master without one): that is a new master roscore is
still starting, which would then refuse to run beside a /run_id not its own.
"""
import os
import signal
import sys
import threading
import time

# Until roslaunch installs its own handlers, as it creates its first node, a SIGINT (the
# mapping daemon's stop signal) must end this process at once. Python's default raises
# KeyboardInterrupt instead, which one of the bare `except:`s on roslaunch's way in can
# swallow: the stop is lost, and the nodes started after it never get one, so the daemon
# stays up until snapd's stop-timeout kills it.
signal.signal(signal.SIGINT, signal.SIG_DFL)

import rosgraph.names  # noqa: E402 (after the SIGINT default, as its import is slow)
import roslaunch  # noqa: E402
import roslaunch.launch  # noqa: E402
from roslaunch.core import RLException, is_machine_local, printerrlog  # noqa: E402

from turtlebot3c_common.master_restart import MasterQuery  # noqa: E402

SETTLE = 5.0  # s the master must stay the same once every node is registered
REGISTER_WAIT = 120.0  # s to wait for the nodes to register (a node that never does: check then)
LAST_LOOK_WAIT = 30.0  # s for the master to answer the last look (the roscore app restarts it)
CALLER = "/roslaunch_joining"


def master_at(uri):
    return MasterQuery(uri, CALLER, timeout=3.0)


def settled_identity(uri, wait=10.0):
    """The master's identity, asked again for up to `wait` s when it does not answer (a loaded machine)."""
    deadline = time.monotonic() + wait
    master = master_at(uri)
    identity = master.identity()
    while identity is None and time.monotonic() < deadline:
        time.sleep(0.2)
        identity = master.identity()
    return identity


def refuse_to_start_a_master(master, *_args):
    raise RLException(f"no ROS master answers at {master.uri} any more; this launch never starts one "
                      "(turtlebot3c.roscore does): stopping, to start again once it answers")


def refuse_to_set_the_run_id(self, param_server, run_id):
    code, _, present = param_server.hasParam("/roslaunch", "/run_id")
    if code == 1 and not present:
        raise RLException(f"the ROS master at {self.config.master.uri} was restarted as this launch started "
                          "(it has no /run_id yet): stopping, to start again against it")
    _check_and_set_run_id(self, param_server, run_id)


class StartWatch:
    """The master the launch's parameters went to, and whether it was still the one once the nodes had started."""

    def __init__(self):
        self.master = None
        self.restarted = None  # the line to end with when the master changed during the start

    def load_parameters(self, runner):
        uri = runner.config.master.uri
        before = settled_identity(uri)
        _load_parameters(runner)
        self.master = settled_identity(uri)
        if before is None or self.master != before:
            raise RLException(f"the ROS master at {uri} was restarted while this launch set its parameters: "
                              "stopping, to start again against the master that runs")

    def launch(self, runner):
        result = _launch(runner)
        names = [rosgraph.names.ns_join(node.namespace, node.name) for node in runner.config.nodes
                 if node.name and is_machine_local(node.machine)]
        threading.Thread(target=self.watch, args=(runner.config.master.uri, names), name="start-watch",
                         daemon=True).start()
        return result

    def watch(self, uri, names):
        deadline = time.monotonic() + REGISTER_WAIT
        master = master_at(uri)
        while time.monotonic() < deadline and not all(master.call("lookupNode", name) for name in names):
            if self.changed(uri, master.identity()):
                return
            time.sleep(0.5)
        time.sleep(SETTLE)
        # The last look must get an answer: a master that was killed is still starting again, or
        # slow to answer on a loaded machine, and taking no answer for "the same master" would
        # leave the nodes on a new master without the parameters.
        self.changed(uri, settled_identity(uri, wait=LAST_LOOK_WAIT))

    def changed(self, uri, now):
        if now is None or now == self.master:
            return False
        self.restarted = (f"the ROS master at {uri} was restarted while this launch started (its parameters "
                          "and some registrations went to the old one): stopping, to start again against it")
        printerrlog(self.restarted)
        os.kill(os.getpid(), signal.SIGTERM)  # roslaunch stops its nodes and returns
        return True


_check_and_set_run_id = roslaunch.launch.ROSLaunchRunner._check_and_set_run_id
_load_parameters = roslaunch.launch.ROSLaunchRunner._load_parameters
_launch = roslaunch.launch.ROSLaunchRunner.launch
START = StartWatch()


def load_parameters_noting_the_master(runner):
    START.load_parameters(runner)


def launch_watching_the_master(runner):
    return START.launch(runner)


if __name__ == "__main__":
    roslaunch.launch.validate_master_launch = refuse_to_start_a_master
    roslaunch.launch.ROSLaunchRunner._check_and_set_run_id = refuse_to_set_the_run_id
    roslaunch.launch.ROSLaunchRunner._load_parameters = load_parameters_noting_the_master
    roslaunch.launch.ROSLaunchRunner.launch = launch_watching_the_master
    roslaunch.main()
    if START.restarted:
        sys.exit(1)
