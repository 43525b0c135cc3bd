"""Notice that the ROS master was restarted, and put back what the new one lacks.

A restarted roscore starts empty: no parameters, no nodes. ROS 1 nodes, rospy
and roscpp alike, register with the master once, when they start, and never
again; after a restart they run on unseen (connections made before carry on,
new subscribers never find them). So the daemons' launch files run a guard
that, when a new master answers, restores the parameters their nodes were
started with and stops those nodes, which roslaunch then respawns: they
register with the new master and read their parameters from it. Our own rospy
nodes need no restart: `turtlebot3c_common.rospy_rejoin` registers them again
in process, keeping their state.
"""
import xmlrpc.client
from typing import Dict, Iterable, Optional


class MasterWatch:
    """Which master answered last; `observe` says when a different one (a restart) answers."""

    def __init__(self):
        self.identity = None

    def observe(self, identity: Optional[str]) -> bool:
        """`identity` of the master that answered now (None: none answered). True on a restart."""
        if identity is None:
            return False
        restarted = self.identity is not None and identity != self.identity
        self.identity = identity
        return restarted


def master_identity(run_id: str, pid: int) -> str:
    """roscore sets a fresh /run_id at every start; with the pid it tells masters apart."""
    return f"{run_id}:{pid}"


def missing_parameters(kept: Dict[str, object], present: Iterable[str]) -> Dict[str, object]:
    """The kept parameters (name -> value, namespaces as dicts) that the master does not have."""
    present = set(present)
    return {name: value for name, value in kept.items() if name not in present}


def flat_parameters(name: str, value: object) -> Dict[str, object]:
    """Parameter `name`'s leaves (name -> value): a namespace (dict) becomes one entry per leaf.

    The master names only leaves in getParamNames, so leaves are what can be compared with it.
    """
    if isinstance(value, dict) and value:
        leaves = {}
        for key, inner in value.items():
            leaves.update(flat_parameters(name.rstrip("/") + "/" + key, inner))
        return leaves
    return {name: value}


class TimeoutTransport(xmlrpc.client.Transport):
    """A master that hangs must not hang its caller."""

    def __init__(self, timeout: float):
        super().__init__()
        self.timeout = timeout

    def make_connection(self, host):
        connection = super().make_connection(host)
        connection.timeout = self.timeout
        return connection


class MasterQuery:
    """Calls to a ROS master's XML-RPC API that give up after `timeout` s (answer None)."""

    def __init__(self, master_uri: str, caller_id: str, timeout: float = 2.0):
        self.proxy = xmlrpc.client.ServerProxy(master_uri, transport=TimeoutTransport(timeout))
        self.caller_id = caller_id
        self.timeout = timeout

    def call(self, method: str, *args):
        """The value of a master API call, or None when it failed or was refused."""
        return call_ros_api(self.proxy, self.caller_id, method, *args)

    def identity(self) -> Optional[str]:
        """The answering master's identity, or None when it did not answer in full.

        A slow master (a loaded machine) may answer one call and time out on the
        next; that must read as "no answer", never as a different master.
        """
        pid = self.call("getPid")
        run_id = self.call("getParam", "/run_id")
        if pid is None or not isinstance(run_id, str):
            return None
        return master_identity(run_id, pid)


def call_ros_api(proxy, caller_id: str, method: str, *args):
    """The value of an XML-RPC call to a ROS API (master or node), or None when it failed or was refused."""
    try:
        code, _, value = getattr(proxy, method)(caller_id, *args)
    except (OSError, xmlrpc.client.Error):
        return None
    return value if code == 1 else None


class KeptParameters:
    """A node's own parameters as last read from the master, to give a new master what it lacks."""

    def __init__(self):
        self.leaves = {}

    def remember(self, namespace: str, value: object) -> None:
        """`value` of the node's namespace as the master answered (None: no answer, keep the last copy)."""
        if value is not None:
            self.leaves = flat_parameters(namespace, value)

    def missing(self, present: Iterable[str]) -> Dict[str, object]:
        """The kept leaves absent from the master's parameter names `present`."""
        return missing_parameters(self.leaves, present)


class NodeRegistrations:
    """What a node has registered with the master: its XML-RPC URI, publications and subscriptions
    ((topic, type) pairs) and services ((name, rosrpc URI) pairs), to register again on its behalf."""

    def __init__(self, uri: str, publications=(), subscriptions=(), services=()):
        self.uri = uri
        self.publications = list(publications)
        self.subscriptions = list(subscriptions)
        self.services = list(services)

    def __eq__(self, other):
        return isinstance(other, NodeRegistrations) and vars(self) == vars(other)

    def __repr__(self):
        return f"NodeRegistrations({vars(self)})"


def node_registrations(node: str, uri: str, system_state, topic_types, service_uri) -> NodeRegistrations:
    """`node`'s registrations from the master's getSystemState and getTopicTypes ([topic, type]
    pairs); `service_uri(name)` is a service's rosrpc URI (lookupService), None if it did not answer."""
    publishers, subscribers, services = system_state
    types = dict((topic, data_type) for topic, data_type in topic_types)

    def topics_of(groups):
        # "*": any type, as rosbag record subscribes; the master lists no type for a topic nobody publishes
        return [(topic, types.get(topic, "*")) for topic, nodes in groups if node in nodes]
    service_uris = [(name, service_uri(name)) for name, nodes in services if node in nodes]
    return NodeRegistrations(uri, topics_of(publishers), topics_of(subscribers),
                             [(name, found) for name, found in service_uris if found])
