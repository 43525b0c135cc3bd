"""The `snapsim` command line: `snap`'s subcommands and flags, on a state root."""
import argparse
import os
import sys
import time

from . import config, environment, hooks, journal, lint, services, snapd
from . import state as state_module
from .layout import Layout
from .state import SnapError
from .supervisor import supervise


def parser():
    top = argparse.ArgumentParser(
        prog="snapsim", description="A local stand-in for snapd and `snap`. All state lives under --root.")
    top.add_argument("--root", default=os.environ.get("SNAPSIM_ROOT"),
                     help="the folder standing for / (default: $SNAPSIM_ROOT)")
    commands = top.add_subparsers(dest="command", required=True)

    install = commands.add_parser("install", help="build the project's snap and install it")
    install.add_argument("project", help="project folder (with snap/snapcraft.yaml)")
    install.add_argument("--dangerous", action="store_true", help="install an unsigned (local) snap")

    remove = commands.add_parser("remove")
    remove.add_argument("snap")
    remove.add_argument("--purge", action="store_true", help="keep no snapshot of the snap's data")

    set_ = commands.add_parser("set")
    set_.add_argument("-t", dest="json", action="store_true", help="parse values strictly as JSON")
    set_.add_argument("-s", dest="string", action="store_true", help="parse values as strings")
    set_.add_argument("snap")
    set_.add_argument("assignments", nargs="+", metavar="key=value")

    get = commands.add_parser("get")
    get.add_argument("-d", dest="document", action="store_true", help="always return a JSON document")
    get.add_argument("snap")
    get.add_argument("keys", nargs="*")

    unset = commands.add_parser("unset")
    unset.add_argument("snap")
    unset.add_argument("keys", nargs="+")

    for action in ("start", "stop", "restart"):
        command = commands.add_parser(action)
        if action == "start":
            command.add_argument("--enable", action="store_true", help="also start it at boot")
        if action == "stop":
            command.add_argument("--disable", action="store_true", help="also do not start it at boot")
        command.add_argument("services", nargs="+", metavar="snap[.app]")

    listing = commands.add_parser("services")
    listing.add_argument("services", nargs="*", metavar="snap[.app]")

    logs = commands.add_parser("logs")
    logs.add_argument("-n", default="10", help='number of lines, or "all"')
    logs.add_argument("-f", dest="follow", action="store_true", help="wait for new lines")
    logs.add_argument("services", nargs="+", metavar="snap[.app]")

    connections = commands.add_parser("connections")
    connections.add_argument("snap", nargs="?")
    connect = commands.add_parser("connect")
    connect.add_argument("plug", metavar="snap:plug")
    connect.add_argument("slot", nargs="?", metavar="[snap]:slot")
    disconnect = commands.add_parser("disconnect")
    disconnect.add_argument("plug", metavar="snap:plug")

    run = commands.add_parser("run", help="run an app as `snap run` does")
    run.add_argument("--shell", action="store_true", help="run bash inside the app's environment and chain")
    run.add_argument("app", metavar="snap.app")
    run.add_argument("args", nargs=argparse.REMAINDER)

    check = commands.add_parser("lint", help="review-tools-like checks of an installed snap's prime tree")
    check.add_argument("snap")

    supervisor = commands.add_parser("_supervise", help="(internal) a service's supervisor")
    supervisor.add_argument("snap")
    supervisor.add_argument("app")
    return top


def main(argv=None):
    args = parser().parse_args(argv)
    if not args.root:
        print("error: give the state root with --root DIR or SNAPSIM_ROOT", file=sys.stderr)
        return 2
    layout = Layout(args.root)
    try:
        return COMMANDS[args.command](layout, args) or 0
    except SnapError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1


def _install(layout, args):
    print(snapd.install(layout, args.project, dangerous=args.dangerous))


def _remove(layout, args):
    print(snapd.remove(layout, args.snap, purge=args.purge))


def _require_configure_hook(layout, snap):
    state_module.snap_state(state_module.read(layout), snap)
    if not hooks.has_hook(services.snap_info(layout, snap), "configure"):
        raise SnapError(f'snap "{snap}" has no "configure" hook')


def _set(layout, args):
    mode = "json" if args.json else "string" if args.string else "auto"
    patch = config.parse_assignments(args.assignments, mode)
    _require_configure_hook(layout, args.snap)
    hooks.run_hook(layout, args.snap, "configure", patch=patch)


def _unset(layout, args):
    patch = [(config.parse_key(key), None) for key in args.keys]
    _require_configure_hook(layout, args.snap)
    hooks.run_hook(layout, args.snap, "configure", patch=patch)


def _get(layout, args):
    values = state_module.snap_state(state_module.read(layout), args.snap)["config"]
    for key in args.keys:
        config.parse_key(key)
    sys.stdout.write(config.snap_get_output(args.snap, values, args.keys, document=args.document))


def _service_action(layout, args):
    targets = services.resolve(layout, args.services)
    services.perform(layout, args.command, targets, enable=getattr(args, "enable", False),
                     disable=getattr(args, "disable", False))
    if args.command != "restart":
        verb = {"start": "Started", "stop": "Stopped"}[args.command]
        print(f"{verb}.")
    else:
        print("Restarted.")


def _services(layout, args):
    names = args.services or sorted(state_module.read(layout)["snaps"])
    sys.stdout.write(services.table(layout, services.resolve(layout, names)))


def _logs(layout, args):
    units = {journal.unit_name(snap, app) for snap, app in services.resolve(layout, args.services)}
    everything = journal.read(layout)
    records = [record for record in everything if record["unit"] in units]
    if args.n != "all":
        records = records[-int(args.n):] if int(args.n) > 0 else []
    for record in records:
        print(journal.format_record(record), flush=True)
    if not args.follow:
        return
    seen = len(everything)  # the read shown above: a line logged since comes next, none is skipped
    try:
        while True:
            time.sleep(0.2)
            everything = journal.read(layout)
            for record in everything[seen:]:
                if record["unit"] in units:
                    print(journal.format_record(record), flush=True)
            seen = len(everything)
    except KeyboardInterrupt:
        return


def _connections(layout, args):
    sys.stdout.write(snapd.connections(layout, args.snap))


def _connect(layout, args):
    snapd.connect(layout, args.plug, connected=True)


def _disconnect(layout, args):
    snapd.connect(layout, args.plug, connected=False)


def _run(layout, args):
    snap, _, app = args.app.partition(".")
    snap_state = state_module.snap_state(state_module.read(layout), snap)
    info = services.snap_info(layout, snap)
    argv, env, cwd = environment.app_command(
        layout, info, snap_state["revision"], app or snap, "shell" if args.shell else "",
        extra_args=args.args, cookie=snap_state["cookie"])
    sys.stdout.flush()
    os.chdir(cwd)
    os.execve(argv[0], argv, env)


def _lint(layout, args):
    revision = state_module.snap_state(state_module.read(layout), args.snap)["revision"]
    problems = lint.lint(layout.snap_mount(args.snap, revision))
    for problem in problems:
        print(problem)
    return 1 if problems else 0


def _supervise(layout, args):
    supervise(layout, args.snap, args.app)


COMMANDS = {
    "install": _install, "remove": _remove, "set": _set, "get": _get, "unset": _unset,
    "start": _service_action, "stop": _service_action, "restart": _service_action,
    "services": _services, "logs": _logs, "connections": _connections, "connect": _connect,
    "disconnect": _disconnect, "run": _run, "lint": _lint, "_supervise": _supervise,
}
