"""What snapd says about the snap: its services, the raw-usb connection and its options.

Through snapctl, which any user may run for `services`, `is-connected` and `get`
(snapd's ctlcmd allows them without root). The three calls run at once, and each
is given up after a deadline, so the status answers quickly even on a loaded robot.
"""
import json
import subprocess
import time
from typing import Dict, NamedTuple, Optional

SNAPCTL_TIMEOUT = 3.0  # s for all three calls together
OPTIONS = ("simulation", "turtlebot3-model", "lds-model", "ros-master-host", "opencr-port", "lds-port", "map")


class Service(NamedTuple):
    enabled: bool
    active: bool


class SnapFacts(NamedTuple):
    services: Optional[Dict[str, Service]]  # app name -> state; None when snapctl did not tell
    raw_usb: Optional[bool]  # None when snapctl did not tell
    options: Dict[str, object]
    problem: str = ""  # what went wrong asking snapctl, if anything


def parse_services(text: str) -> Dict[str, Service]:
    """`snapctl services` (Service, Startup, Current, Notes) -> {app: Service}."""
    services = {}
    for line in text.splitlines()[1:]:
        words = line.split()
        if len(words) >= 3:
            app = words[0].split(".", 1)[-1]
            services[app] = Service(enabled=words[1] == "enabled", active=words[2] == "active")
    return services


def read_snap_facts(timeout: float = SNAPCTL_TIMEOUT) -> SnapFacts:
    commands = {"services": ["snapctl", "services"], "raw-usb": ["snapctl", "is-connected", "raw-usb"],
                "options": ["snapctl", "get", "-d"] + list(OPTIONS)}
    try:
        running = {name: subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                   for name, command in commands.items()}
    except OSError as error:
        return SnapFacts(None, None, {}, f"cannot run snapctl: {error}")
    deadline = time.monotonic() + timeout
    results, problems = {}, []
    for name, process in running.items():
        try:
            out, err = process.communicate(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            problems.append(f"snapctl {name} did not answer within {timeout:.0f} s")
            continue
        results[name] = (process.returncode, out, err.strip())
    services = options = raw_usb = None
    if "services" in results:
        code, out, err = results["services"]
        services = parse_services(out) if code == 0 else None
        if code != 0:
            problems.append(f"snapctl services: {err}")
    if "raw-usb" in results:
        raw_usb = results["raw-usb"][0] == 0  # is-connected answers by its exit status
    if "options" in results:
        code, out, err = results["options"]
        try:
            options = json.loads(out) if code == 0 else None
        except ValueError:
            options = None
        if options is None:
            problems.append(f"snapctl get: {err or out.strip()}")
    return SnapFacts(services, raw_usb, options or {}, "; ".join(problems))
