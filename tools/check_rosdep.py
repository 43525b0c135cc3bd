#!/usr/bin/env python3
"""Check every package.xml of the workspace: it lists exactly what its package uses, and each
dependency resolves with rosdep for noetic on Ubuntu focal.

Exactly what it uses (package_imports.py): the modules its Python imports, the packages its
launch files run, and the commands its code runs. A missing key would fail on the robot; an
extra one installs what nobody uses (a teleop-only install pulling in the OpenCR stack).

snapcraft's catkin plugin runs rosdep on each package.xml when it builds the snap; a key that
does not resolve there fails the build. This check reads the part of that database our
package.xml files use, kept in tools/data/rosdistro (refresh_check_data.py cuts it from a full
snapshot): a key resolves if it is a package of this workspace, a package released for noetic,
or a rosdep key with a rule for ubuntu focal. The data is kept in the repository so that the
check runs in any clone; without it the check fails.

Usage: check_rosdep.py SRC_DIR [--rosdistro DIR]
"""
import argparse
import sys
from pathlib import Path

import yaml
from catkin_pkg.packages import find_packages
from package_imports import used_keys

# Used but deliberately not a dependency: installed where it is wanted, not in the snap.
NOT_DEPENDED_ON = {
    "rviz": "open_rviz:=true runs RViz, which belongs on the owner's desktop, not in the robot's snap",
}

ROS_CONDITION_CONTEXT = {"ROS_VERSION": "1", "ROS_DISTRO": "noetic", "ROS_PYTHON_VERSION": "3"}
DEPENDENCY_KINDS = (
    "buildtool_depends", "build_depends", "build_export_depends", "exec_depends",
    "test_depends", "doc_depends",
)


def released_noetic_packages(distribution_file):
    distribution = yaml.safe_load(distribution_file.read_text())
    released = set()
    for repository_name, repository in distribution["repositories"].items():
        release = repository.get("release")
        if not release or "version" not in release:
            continue
        released.update(release.get("packages", [repository_name]))
    return released


def focal_rule(rule):
    """The part of a rosdep rule that applies to ubuntu focal, or None if there is none."""
    ubuntu = (rule or {}).get("ubuntu")
    if isinstance(ubuntu, dict) and not set(ubuntu) & {"apt", "pip", "source"}:
        ubuntu = ubuntu.get("focal", ubuntu.get("*"))
    return ubuntu or None


def rosdep_keys_for_focal(rosdep_files):
    keys = set()
    for path in rosdep_files:
        for key, rule in yaml.safe_load(path.read_text()).items():
            if focal_rule(rule) is not None:
                keys.add(key)
    return keys


def unresolved_dependencies(packages, resolvable):
    """(package, key) pairs whose key resolves nowhere."""
    problems = []
    for package in packages:
        package.evaluate_conditions(ROS_CONDITION_CONTEXT)
        for kind in DEPENDENCY_KINDS:
            for dependency in getattr(package, kind):
                if dependency.evaluated_condition and dependency.name not in resolvable:
                    problems.append((package.name, dependency.name))
    return problems


def dependency_mismatches(packages, src):
    """(package, message) for each key a package uses but does not list, or lists but does not use."""
    problems = []
    for package in packages:
        if package.is_metapackage():
            continue
        package.evaluate_conditions(ROS_CONDITION_CONTEXT)
        declared = {dependency.name for kind in DEPENDENCY_KINDS for dependency in getattr(package, kind)
                    if dependency.evaluated_condition} - {"catkin"}
        used = used_keys(Path(src) / package.name)
        for key in sorted(set(used) - declared - set(NOT_DEPENDED_ON)):
            problems.append((package.name, f"uses '{key}' ({used[key]}) but package.xml does not list it"))
        for key in sorted(declared - set(used)):
            problems.append((package.name, f"lists '{key}' but nothing in the package uses it"))
    return problems


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("src", type=Path)
    default_rosdistro = Path(__file__).resolve().parent / "data" / "rosdistro"
    parser.add_argument("--rosdistro", type=Path, default=default_rosdistro)
    args = parser.parse_args(argv)

    distribution = args.rosdistro / "noetic" / "distribution.yaml"
    rosdep_files = sorted((args.rosdistro / "rosdep").glob("*.yaml"))
    if not distribution.is_file() or not rosdep_files:
        print(f"check_rosdep: no rosdep data at {args.rosdistro} (noetic/distribution.yaml and rosdep/*.yaml; "
              "tools/refresh_check_data.py writes them)", file=sys.stderr)
        return 1
    packages = list(find_packages(str(args.src)).values())
    problems = dependency_mismatches(packages, args.src)
    resolvable = {package.name for package in packages}
    try:
        resolvable |= released_noetic_packages(distribution)
        resolvable |= rosdep_keys_for_focal(rosdep_files)
    except (yaml.YAMLError, KeyError, AttributeError, TypeError) as error:
        print(f"check_rosdep: cannot read the rosdep data at {args.rosdistro}: {' '.join(str(error).split())}",
              file=sys.stderr)
        return 1
    problems += [(name, f"dependency '{key}' does not resolve with rosdep for noetic on focal in {args.rosdistro}"
                        " (a new key? tools/refresh_check_data.py looks it up in the full snapshot)")
                 for name, key in unresolved_dependencies(packages, resolvable)]
    for package_name, message in problems:
        print(f"check_rosdep: {package_name}: {message}", file=sys.stderr)
    if not problems:
        print(f"check_rosdep: {len(packages)} packages list exactly what they use, and every dependency resolves")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
