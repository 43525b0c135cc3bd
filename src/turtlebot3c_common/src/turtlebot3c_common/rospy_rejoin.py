"""Keep a rospy node in the ROS graph when the master restarts, in process and with its state.

The thin rospy side of `turtlebot3c_common.master_restart` (the only module of the
package that imports rospy: it works on rospy's own registration machinery).

rospy registers a node's publishers, subscribers and services with the master once,
at start; a restarted roscore knows none of them, so new subscribers, publishers and
service clients never find the node, though connections made before carry on. A node
that calls `rejoin_restarted_masters()` after `rospy.init_node` gets a daemon thread
that asks the master who it is every `period` s; when a new master (a new /run_id)
answers, it sets the node's own private parameters the new master lacks, then
registers every publisher, subscriber and service of the process again through
rospy's RegManager, the registration listener rospy itself registers with. A
subscriber's registration returns the topic's publishers, which the RegManager
connects to (as on a publisherUpdate), and the master tells it of later ones. The
node keeps running throughout: SLAM its map, AMCL its particles, move_base its goal.
"""
import threading
import time

import rosgraph
import rospy
from rospy.impl.registration import (
    Registration,
    RegManager,
    get_registration_listeners,
    get_service_manager,
    get_topic_manager,
)

from turtlebot3c_common.master_restart import KeptParameters, MasterQuery, MasterWatch

PERIOD = 0.5  # s between looks at the master: its restart is noticed within this
PARAMETERS_EVERY = 10  # looks between refreshes of the copy of the node's private parameters


def rejoin_restarted_masters(period=PERIOD, on_rejoined=None):
    """Start watching the master for this (initialised) node; returns the started thread.
    `on_rejoined()`, if given, is called (in that thread) once the node is registered with a new master."""
    rejoiner = Rejoiner(MasterQuery(rosgraph.get_master_uri(), rospy.get_name()), rospy.get_name(), period,
                        on_rejoined)
    thread = threading.Thread(target=rejoiner.run, name="master-rejoin", daemon=True)
    thread.start()
    return thread


def registrar():
    """rospy's RegManager of this process, once it has registered with a master (None before)."""
    # A copy without the listeners' lock: rospy holds it while a new publisher waits for an absent master.
    listeners = list(get_registration_listeners().listeners)
    return next((listener for listener in listeners if isinstance(listener, RegManager)), None)


def registrations():
    """(name, type or service URI, kind) of every publisher, subscriber and service of this process."""
    topics, services = get_topic_manager(), get_service_manager()
    return ([(name, data_type, Registration.PUB) for name, data_type in topics.get_publications()]
            + [(name, uri, Registration.SRV) for name, uri in services.get_services()]
            + [(name, data_type, Registration.SUB) for name, data_type in topics.get_subscriptions()])


class Rejoiner:
    def __init__(self, master, node_name, period, on_rejoined=None):
        self.master = master
        self.node_name = node_name
        self.period = period
        self.on_rejoined = on_rejoined
        self.watch = MasterWatch()
        self.parameters = KeptParameters()
        self.parameters_owed = False  # the new master still lacks some of the node's parameters
        self.looks = 0

    def run(self):
        while not rospy.is_shutdown():
            identity = self.master.identity()
            if self.watch.observe(identity):
                self.rejoin()
            elif identity is not None and self.parameters_owed:
                self.restore_parameters()
            elif identity is not None and self.looks % PARAMETERS_EVERY == 0:
                self.parameters.remember(self.node_name, self.master.call("getParam", self.node_name))
            self.looks += 1
            time.sleep(self.period)  # wall time: a simulated clock stops with the master's nodes

    def restore_parameters(self):
        """Set the node's kept parameters the master lacks. A call a loaded master did not answer
        in time leaves them owed, for the next look (the copy is not read back from the master
        meanwhile: it would lack them)."""
        present = self.master.call("getParamNames")
        if present is None:
            self.parameters_owed = True
            return
        self.parameters_owed = False
        for name, value in self.parameters.missing(present).items():
            if self.master.call("setParam", name, value) is None:
                self.parameters_owed = True

    def rejoin(self):
        rospy.logwarn("%s: the ROS master was restarted: registering with the new one", self.node_name)
        self.restore_parameters()
        manager = registrar()
        if manager is None:  # never registered: rospy's own start-up registration is still trying
            return
        for name, data_type_or_uri, kind in registrations():
            manager.reg_added(name, data_type_or_uri, kind)  # retries until the master answers
        rospy.loginfo("%s: registered again with the new ROS master", self.node_name)
        if self.on_rejoined is not None:
            self.on_rejoined()
