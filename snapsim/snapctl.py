"""`snapctl`, as apps and hooks see it: get, set, unset, start, stop, restart, services, is-connected.

The caller is identified by $SNAP_COOKIE (hooks: a context with a config
transaction and a queue of service actions; apps: their snap's cookie, where
changes apply at once). Only root may change things, as with snapd.
"""
import argparse
import os
import sys

from . import config, contexts
from . import state as state_module
from .layout import Layout
from .state import SnapError

NON_ROOT_ALLOWED = {"get", "services", "is-connected"}


def find_context(layout):
    """(snap, hook context cookie or None) of the caller."""
    cookie = os.environ.get("SNAP_COOKIE") or os.environ.get("SNAP_CONTEXT") or ""
    if cookie and contexts.context_path(layout, cookie).exists():
        return contexts.read_context(layout, cookie)["snap"], cookie
    for name, snap in state_module.read(layout)["snaps"].items():
        if cookie and snap.get("cookie") == cookie:
            return name, None
    raise SnapError("cannot use snapctl outside a snap: no valid SNAP_COOKIE")


def parser():
    top = argparse.ArgumentParser(prog="snapctl")
    commands = top.add_subparsers(dest="command", required=True)
    get = commands.add_parser("get")
    get.add_argument("-t", dest="typed", action="store_true", help="strict typing with nulls and quoted strings")
    get.add_argument("-d", dest="document", action="store_true", help="always return a document")
    get.add_argument("keys", nargs="*")
    set_ = commands.add_parser("set")
    set_.add_argument("-t", dest="json", action="store_true", help="parse the value strictly as JSON")
    set_.add_argument("-s", dest="string", action="store_true", help="parse the value as a string")
    set_.add_argument("assignments", nargs="+")
    unset = commands.add_parser("unset")
    unset.add_argument("keys", nargs="+")
    for action in ("start", "stop", "restart"):
        command = commands.add_parser(action)
        if action == "start":
            command.add_argument("--enable", action="store_true")
        if action == "stop":
            command.add_argument("--disable", action="store_true")
        command.add_argument("--no-wait", action="store_true")
        command.add_argument("services", nargs="+")
    listing = commands.add_parser("services")
    listing.add_argument("services", nargs="*")
    connected = commands.add_parser("is-connected")
    connected.add_argument("plug")
    return top


def main(layout, argv):
    args = parser().parse_args(argv)
    if os.geteuid() != 0 and args.command not in NON_ROOT_ALLOWED:
        raise SnapError(f'cannot use "{args.command}" with uid {os.geteuid()}, try with sudo')
    snap, cookie = find_context(layout)

    if args.command == "get":
        if not args.keys:
            raise SnapError("get which option?")
        for key in args.keys:
            config.parse_key(key)
        values = contexts.read_context(layout, cookie)["config"] if cookie else _committed(layout, snap)
        sys.stdout.write(config.snapctl_get_output(values, args.keys, typed=args.typed, document=args.document))
        return 0

    if args.command in ("set", "unset"):
        if args.command == "set":
            mode = "json" if args.json else "string" if args.string else "auto"
            patch = config.parse_assignments(args.assignments, mode)
        else:
            patch = [(config.parse_key(key), None) for key in args.keys]
        with state_module.locked(layout) as current:
            if cookie:
                context = contexts.read_context(layout, cookie)
                context["config"] = config.apply_patch(context["config"], patch)
                contexts.write_context(layout, cookie, context)
            else:
                snap_state = current["snaps"][snap]
                snap_state["config"] = config.purge_nulls(config.apply_patch(snap_state["config"], patch))
        return 0

    # Imported here, not above: services brings in the supervisor and YAML, and most calls are a `get`.
    from . import services

    if args.command in ("start", "stop", "restart"):
        flags = {"enable": getattr(args, "enable", False), "disable": getattr(args, "disable", False)}
        targets = services.resolve(layout, args.services, own_snap=snap)
        if cookie:
            with state_module.locked(layout):
                context = contexts.read_context(layout, cookie)
                context["queued"].append([args.command, args.services, flags])
                contexts.write_context(layout, cookie, context)
        else:
            services.perform(layout, args.command, targets, **flags)
        return 0

    if args.command == "services":
        names = args.services or [snap]
        sys.stdout.write(services.table(layout, services.resolve(layout, names, own_snap=snap)))
        return 0

    if args.command == "is-connected":
        connections = state_module.read(layout)["snaps"][snap].get("connections", {})
        return 0 if connections.get(args.plug) else 1
    raise SnapError(f"unknown command {args.command}")


def _committed(layout, snap):
    return state_module.read(layout)["snaps"][snap]["config"]


def command_line(argv):
    """`python3 -m snapsim.snapctl ROOT ARGS...`, the base snap's snapctl (snapd.ensure_system writes it)."""
    root, *arguments = argv
    try:
        return main(Layout(root), arguments)
    except SnapError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(command_line(sys.argv[1:]))
