"""Notice that the ROS master was restarted, and put back what the new one lacks.

A restarted roscore starts empty: no parameters, no nodes. ROS 1 nodes, rospy
and roscpp alike, register with the master once, when they start, and never
again; after a restart they run on unseen (connections made before carry on,
new subscribers never find them). So the daemons' launch files run a guard
that, when a new master answers, restores the parameters their nodes were
started with and stops those nodes, which roslaunch then respawns: they
register with the new master and read their parameters from it.
"""
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
