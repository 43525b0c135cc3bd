#!/usr/bin/env python3
"""Refresh the data the static checks read, kept in the repository (tools/data/) so that they run
in any clone: the rosdep keys and Noetic distribution entries our package.xml files use, cut from
a full rosdistro snapshot, and snapcraft 7's core20 schema.

Run it after adding a dependency to a package.xml, where the full snapshot is at hand
(../shared beside the repository, by default). It writes only what check_rosdep.py and
check_snapcraft_schema.py read; a missing input is an error, and nothing is written then.

Usage: refresh_check_data.py [--rosdistro DIR] [--schema FILE] [--src DIR] [--out DIR]
"""
import argparse
import json
import os
import re
import sys
from pathlib import Path

import yaml
from catkin_pkg.packages import find_packages
from check_rosdep import DEPENDENCY_KINDS, ROS_CONDITION_CONTEXT

TOOLS = Path(__file__).resolve().parent
REPO = TOOLS.parent
SHARED = REPO.parent / "shared"
HEADER = ("# Cut by tools/refresh_check_data.py from {source}{commit}:\n"
          "# only the entries the workspace's package.xml files use. Do not edit; refresh instead.\n")


class MissingInput(Exception):
    pass


def dependency_keys(src):
    """Every dependency name of the workspace's package.xml files, less the workspace's own packages."""
    packages = list(find_packages(str(src)).values())
    keys = set()
    for package in packages:
        package.evaluate_conditions(ROS_CONDITION_CONTEXT)
        keys.update(dependency.name for kind in DEPENDENCY_KINDS for dependency in getattr(package, kind)
                    if dependency.evaluated_condition)
    return keys - {package.name for package in packages}


def read_yaml(path):
    if not path.is_file():
        raise MissingInput(f"no {path}")
    return yaml.safe_load(path.read_text())


def released_entries(distribution, keys):
    """The distribution's repositories that release one of `keys`, with only those packages and the version."""
    entries = {}
    for name, repository in distribution["repositories"].items():
        release = repository.get("release") or {}
        if "version" not in release:
            continue
        used = sorted(set(release.get("packages", [name])) & keys)
        if used:
            entries[name] = {"release": {"packages": used, "version": release["version"]}}
    return {"repositories": entries}


def snapshot_commit(rosdistro):
    """The rosdistro commit its README names, for the header (empty if it names none)."""
    readme = rosdistro / "README.md"
    found = re.search(r"\b[0-9a-f]{40}\b", readme.read_text()) if readme.is_file() else None
    return f" (ros/rosdistro {found.group(0)})" if found else ""


def cut_rosdistro(rosdistro, keys):
    """{relative path: YAML text} of the cut: noetic/distribution.yaml and one file per rosdep file."""
    header = HEADER.format(source=os.path.relpath(rosdistro, REPO), commit=snapshot_commit(rosdistro))
    distribution = released_entries(read_yaml(rosdistro / "noetic" / "distribution.yaml"), keys)
    files = {"noetic/distribution.yaml": distribution}
    rosdep_files = sorted((rosdistro / "rosdep").glob("*.yaml"))
    if not rosdep_files:
        raise MissingInput(f"no rosdep/*.yaml in {rosdistro}")
    for path in rosdep_files:
        rules = read_yaml(path)
        files[f"rosdep/{path.name}"] = {key: rules[key] for key in sorted(keys & set(rules))}
    return {name: header + yaml.safe_dump(content, sort_keys=True, default_flow_style=False)
            for name, content in files.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rosdistro", type=Path, default=SHARED / "rosdistro")
    parser.add_argument("--schema", type=Path, default=SHARED / "snapcraft" / "snapcraft.json")
    parser.add_argument("--src", type=Path, default=REPO / "src")
    parser.add_argument("--out", type=Path, default=TOOLS / "data")
    args = parser.parse_args(argv)
    try:
        cut = cut_rosdistro(args.rosdistro, dependency_keys(args.src))
        if not args.schema.is_file():
            raise MissingInput(f"no {args.schema}")
        schema = args.schema.read_text()
        json.loads(schema)  # a broken download must not replace a good copy
    except (MissingInput, ValueError, yaml.YAMLError) as error:
        print(f"refresh_check_data: {error}; nothing written", file=sys.stderr)
        return 1
    for name, text in cut.items():
        path = args.out / "rosdistro" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    (args.out / "snapcraft-core20.json").write_text(schema)
    print(f"refresh_check_data: wrote {len(cut)} rosdistro files and the core20 schema under {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
