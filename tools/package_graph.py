#!/usr/bin/env python3
"""Print the workspace's package graph: what each catkin package depends on among ours, and what
else it pulls in. With --closure PACKAGE, everything installing PACKAGE installs (its exec_depend
closure), one key a line.

Reads only package.xml files (no ROS, no build). See docs/architecture.md for the graph's shape.

Usage: tools/package_graph.py [SRC] [--closure PACKAGE]
"""
import argparse
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

RUN_DEPENDENCY_TAGS = ("depend", "exec_depend", "run_depend")


def read_dependencies(src):
    """{package: [exec dependency keys, in package.xml's order]} of the packages under src."""
    graph = {}
    for manifest in sorted(Path(src).glob("*/package.xml")):
        root = ElementTree.parse(manifest).getroot()
        graph[root.findtext("name")] = [element.text.strip() for tag in RUN_DEPENDENCY_TAGS
                                        for element in root.findall(tag)]
    return graph


def closure(graph, package):
    """Every key installing `package` installs, through our packages' dependencies (sorted)."""
    seen, pending = set(), [package]
    while pending:
        for key in graph.get(pending.pop(), []):
            if key not in seen:
                seen.add(key)
                pending.append(key)
    return sorted(seen)


def print_graph(graph):
    ours = set(graph)
    for package, keys in graph.items():
        internal = [key for key in keys if key in ours]
        external = [key for key in keys if key not in ours]
        print(f"{package} -> {', '.join(internal) or '(none of ours)'}")
        print(f"    also: {', '.join(external) or '-'}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("src", nargs="?", default=Path(__file__).resolve().parent.parent / "src", type=Path)
    parser.add_argument("--closure", metavar="PACKAGE")
    args = parser.parse_args(argv)
    graph = read_dependencies(args.src)
    if args.closure:
        if args.closure not in graph:
            print(f"package_graph: no package {args.closure!r} in {args.src}", file=sys.stderr)
            return 2
        print("\n".join(closure(graph, args.closure)))
    else:
        print_graph(graph)
    return 0


if __name__ == "__main__":
    sys.exit(main())
