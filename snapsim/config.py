"""Snap configuration as snapd keeps it: option names, JSON typing, patches, `get` output.

- names: dotted paths of parts matching snapd's `^(?:[a-z0-9]+-?)*[a-z](?:-?[a-z0-9])*$`
- `key=value`: value decoded as JSON (numbers, true/false, objects...), else kept as
  a string; `-s` forces a string, `-t` requires JSON; `key!` unsets
- a patch value of None unsets the option when the transaction commits
"""
import copy
import json
import re

from .state import SnapError

_PART = re.compile(r"^(?:[a-z0-9]+-?)*[a-z](?:-?[a-z0-9])*$")


class NoOption(SnapError):
    pass


def parse_key(key):
    parts = key.split(".")
    if not all(_PART.match(part) for part in parts):
        raise SnapError(f"invalid option name: {json.dumps(key)}")
    return parts


def decode_value(text, mode="auto"):
    """A `snap set` value: mode "auto" (JSON if it parses, else string), "string" or "json"."""
    if mode == "string":
        return text
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except ValueError:
        if mode == "json":
            raise SnapError(f"failed to parse JSON: {text}") from None
        return text


def _reject_constant(name):
    # Go's JSON decoder knows no NaN or Infinity; such values stay strings.
    raise ValueError(name)


def parse_assignments(arguments, mode="auto"):
    """`key=value` and `key!` arguments -> [(key parts, value or None)]."""
    patch = []
    for argument in arguments:
        if "=" in argument:
            key, text = argument.split("=", 1)
            patch.append((parse_key(key), decode_value(text, mode)))
        elif argument.endswith("!"):
            patch.append((parse_key(argument[:-1]), None))
        else:
            raise SnapError(f"invalid configuration: {json.dumps(argument)} (want key=value)")
    return patch


def apply_patch(config, patch):
    """A copy of `config` with the patch applied (None values kept until `purge_nulls`)."""
    config = copy.deepcopy(config)
    for parts, value in patch:
        node = config
        for depth, part in enumerate(parts[:-1]):
            child = node.setdefault(part, {})
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                raise SnapError(f'option {json.dumps(".".join(parts[:depth + 1]))} is not a map')
            node = child
        node[parts[-1]] = copy.deepcopy(value)
    return config


def purge_nulls(config):
    """What is stored when a transaction commits: unset options removed, empty maps too."""
    clean = {}
    for key, value in config.items():
        if isinstance(value, dict):
            value = purge_nulls(value)
            if not value:
                continue
        if value is not None:
            clean[key] = value
    return clean


def lookup(config, key):
    """The value of a dotted key; NoOption if unset."""
    node = config
    for part in parse_key(key):
        if not isinstance(node, dict) or node.get(part) is None:
            raise NoOption(f"no {json.dumps(key)} configuration option")
        node = node[part]
    return node


def to_json(value):
    """JSON as Go's json.MarshalIndent(v, "", "\\t") writes it (sorted keys, HTML-safe)."""
    text = json.dumps(value, indent="\t", sort_keys=True, separators=(",", ": "), ensure_ascii=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def snapctl_get_output(config, keys, typed=False, document=False):
    """What `snapctl get [-t] [-d] KEY...` prints (an unset key is "" or, with -t, null)."""
    values = {}
    for key in keys:
        try:
            values[key] = lookup(config, key)
        except NoOption:
            values[key] = None if typed else ""
    if len(keys) == 1 and not document:
        value = values[keys[0]]
        if isinstance(value, str) and not typed:
            return value + "\n"
        return to_json(value) + "\n"
    return to_json(values) + "\n"


def snap_get_output(snap, config, keys, document=False):
    """What `snap get [-d] SNAP [KEY...]` prints; an unset key is an error."""
    if not keys:
        if document:
            return to_json(config) + "\n"
        return _table([(key, config[key]) for key in sorted(config)])
    values = {}
    for key in keys:
        try:
            values[key] = lookup(config, key)
        except NoOption:
            raise SnapError(f'snap {json.dumps(snap)} has no {json.dumps(key)} configuration option') from None
    if document:
        return to_json(values) + "\n"
    if len(keys) == 1:
        value = values[keys[0]]
        if isinstance(value, dict):
            return _table([(f"{keys[0]}.{key}", value[key]) for key in sorted(value)])
        return (value if isinstance(value, str) else to_json(value)) + "\n"
    return _table(sorted(values.items()))


def _table(rows):
    shown = [(key, "{...}" if isinstance(value, dict) else value if isinstance(value, str) else to_json(value))
             for key, value in rows]
    width = max([len("Key")] + [len(key) for key, _ in shown])
    lines = [f"{'Key':<{width}}  Value"] + [f"{key:<{width}}  {value}" for key, value in shown]
    return "\n".join(lines) + "\n"
