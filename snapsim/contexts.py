"""Hook contexts: the file, named by a running hook's cookie, that holds its config transaction and
its queued service actions. Apart from hooks.py so that snapctl, a new process for every call a hook
or app makes, imports no more than it needs."""
import json
import os


def context_path(layout, cookie):
    return layout.contexts_dir / f"{cookie}.json"


def read_context(layout, cookie):
    return json.loads(context_path(layout, cookie).read_text())


def write_context(layout, cookie, context):
    path = context_path(layout, cookie)
    temporary = path.with_suffix(".tmp")
    temporary.write_text(json.dumps(context))
    os.replace(temporary, path)
