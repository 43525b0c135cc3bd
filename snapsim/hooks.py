"""Running hooks as snapd does: as root, in a context with a config transaction.

A hook's `snapctl set` changes only its context's copy of the configuration;
it is committed when the hook succeeds and dropped when it fails (so a
rejected `snap set` changes nothing). `snapctl start/stop/restart` in a hook
are queued and performed after the hook has succeeded.
"""
import secrets
import subprocess

from . import config, environment, services
from . import state as state_module
from .contexts import context_path, read_context, write_context
from .state import SnapError

HOOK_TIMEOUTS = {"configure": 300.0, "default-configure": 300.0}
DEFAULT_HOOK_TIMEOUT = 600.0
TASK_TITLES = {
    "install": 'Run install hook of "{snap}" snap if present',
    "configure": 'Run configure hook of "{snap}" snap if present',
    "remove": 'Run remove hook of "{snap}" snap if present',
    "pre-refresh": 'Run pre-refresh hook of "{snap}" snap if present',
    "post-refresh": 'Run post-refresh hook of "{snap}" snap if present',
}


def has_hook(snap_info, hook):
    return hook in (snap_info.get("hooks") or {})


def run_hook(layout, snap, hook, patch=(), revision=None):
    """Run `hook` of `snap` with the config patch; commit and perform queued actions on success.

    Raises SnapError (snapd's task error text) when the hook fails or times out.
    A missing hook commits the patch directly.
    """
    current = state_module.read(layout)["snaps"][snap]
    revision = revision or current["revision"]
    info = services.snap_info(layout, snap) if revision == current["revision"] else _snap_yaml(layout, snap, revision)
    cookie = secrets.token_hex(16)
    layout.contexts_dir.mkdir(parents=True, exist_ok=True)
    with state_module.locked(layout) as locked_state:
        proposed = config.apply_patch(locked_state["snaps"][snap]["config"], patch)
        write_context(layout, cookie, {"snap": snap, "hook": hook, "config": proposed, "queued": []})
    try:
        if has_hook(info, hook):
            _execute(layout, snap, info, revision, hook, cookie)
        with state_module.locked(layout) as locked_state:
            context = read_context(layout, cookie)
            locked_state["snaps"][snap]["config"] = config.purge_nulls(context["config"])
        for action, names, flags in context["queued"]:
            services.perform(layout, action, services.resolve(layout, names, own_snap=snap), **flags)
    finally:
        context_path(layout, cookie).unlink(missing_ok=True)


def _execute(layout, snap, info, revision, hook, cookie):
    argv, env, cwd = environment.hook_command(layout, info, revision, hook, cookie)
    timeout = HOOK_TIMEOUTS.get(hook, DEFAULT_HOOK_TIMEOUT)
    log = layout.state_dir / "hook-logs" / f"{snap}.{hook}.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    try:
        done = subprocess.run(argv, env=env, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, timeout=timeout, start_new_session=True)
    except subprocess.TimeoutExpired as expired:
        output = (expired.output or b"").decode(errors="replace")
        log.write_text(output)
        raise SnapError(_task_error(snap, hook, f"exceeded maximum runtime of {timeout:g}s")) from None
    output = done.stdout.decode(errors="replace")
    log.write_text(output)
    if done.returncode != 0:
        raise SnapError(_task_error(snap, hook, output.strip() or f"exit status {done.returncode}"))


def _task_error(snap, hook, detail):
    title = TASK_TITLES.get(hook, f'Run hook {hook} of snap "{{snap}}"').format(snap=snap)
    return f'cannot perform the following tasks:\n- {title} (run hook "{hook}": {detail})'


def _snap_yaml(layout, snap, revision):
    import yaml
    return yaml.safe_load((layout.snap_mount(snap, revision) / "meta" / "snap.yaml").read_text())
