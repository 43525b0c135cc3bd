"""Whether the ROS master answers, and what is registered with it, within a deadline.

The master's name may not resolve (an mDNS `.local` name without avahi), or resolve
slowly: name lookups take no socket timeout, so the whole question runs in a thread
that is given up at the deadline.
"""
import socket
import threading
import xmlrpc.client
from typing import Dict, List, NamedTuple, Optional
from urllib.parse import urlparse

from turtlebot3c_common.master_restart import TimeoutTransport

MASTER_TIMEOUT = 1.5  # s
CALLER_ID = "/turtlebot3c_status"


class MasterFacts(NamedTuple):
    uri: str
    answers: bool
    problem: str = ""  # why it does not: "does not resolve", "refused the connection", "did not answer"
    publishers: Dict[str, List[str]] = {}  # topic -> nodes
    nodes: frozenset = frozenset()


def host_of(uri: str) -> str:
    return urlparse(uri).hostname or ""


def ask_master(uri: str, timeout: float = MASTER_TIMEOUT) -> MasterFacts:
    result: List[Optional[MasterFacts]] = [None]

    def ask():
        result[0] = _ask(uri, timeout)

    worker = threading.Thread(target=ask, daemon=True)
    worker.start()
    worker.join(timeout + 0.2)
    return result[0] or MasterFacts(uri, False, f"did not answer within {timeout:.1f} s")


def _ask(uri: str, timeout: float) -> MasterFacts:
    proxy = xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(timeout))
    try:
        code, message, state = proxy.getSystemState(CALLER_ID)
    except socket.gaierror:
        return MasterFacts(uri, False, f"its host {host_of(uri)} does not resolve")
    except ConnectionRefusedError:
        return MasterFacts(uri, False, "nothing listens there")
    except (OSError, xmlrpc.client.Error) as error:
        return MasterFacts(uri, False, f"it did not answer ({error})")
    if code != 1:
        return MasterFacts(uri, False, f"it refused the question: {message}")
    publishers = {topic: list(nodes) for topic, nodes in state[0]}
    nodes = frozenset(node for table in state for _, names in table for node in names)
    return MasterFacts(uri, True, "", publishers, nodes)
