"""The workspace's shape: dependencies point down, a teleop-only install needs no OpenCR stack,
and the planar pose maths exists once."""
import ast
import runpy
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGE_GRAPH = runpy.run_path(str(REPO / "tools" / "package_graph.py"))  # the tool's functions
GRAPH = PACKAGE_GRAPH["read_dependencies"](REPO / "src")
# Each package above those it may depend on; the simulator (tests only) may use any.
LAYERS = [
    {"turtlebot3c_common", "turtlebot3c_description"},
    {"turtlebot3c_bringup", "turtlebot3c_teleop", "turtlebot3c_maps"},
    {"turtlebot3c_slam", "turtlebot3c_navigation", "turtlebot3c_status"},
    {"turtlebot3c_sim", "turtlebot3c"},
]


def closure(package):
    return set(PACKAGE_GRAPH["closure"](GRAPH, package))


def layer_of(package):
    return next(index for index, layer in enumerate(LAYERS) if package in layer)


def test_every_package_is_in_a_layer_and_depends_only_on_lower_layers():
    assert set(GRAPH) == set().union(*LAYERS)
    for package, keys in GRAPH.items():
        for dependency in set(keys) & set(GRAPH):
            assert layer_of(dependency) < layer_of(package), f"{package} depends on {dependency}"


def test_a_teleop_only_install_pulls_in_neither_the_opencr_stack_nor_the_other_capabilities():
    teleop = closure("turtlebot3c_teleop")
    assert {"turtlebot3c_common", "topic_tools"} <= teleop
    assert not teleop & {"dynamixel_sdk", "python3-serial", "turtlebot3c_bringup", "turtlebot3c_maps"}
    assert {"dynamixel_sdk", "python3-serial"} <= closure("turtlebot3c_bringup")  # what teleop no longer drags in


@pytest.mark.parametrize("package", ["turtlebot3c_slam", "turtlebot3c_navigation"])
def test_mapping_and_navigation_need_no_drivers(package):
    assert "dynamixel_sdk" not in closure(package)


def python_sources():
    for folder in ("src", "tools", "snapsim", "testkit", "demo", "benchmarks"):
        for path in sorted((REPO / folder).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts and (
                    path.suffix == ".py" or path.read_bytes().startswith(b"#!/usr/bin/env python3")):
                yield path


def test_angle_wrapping_and_quaternion_maths_are_defined_once():
    names = {"wrap", "wrap_angle", "normalize_angle", "_wrap", "yaw_to_quaternion", "quaternion_to_yaw",
             "yaw_quaternion", "quaternion_from_yaw", "yaw_from_quaternion", "compose", "inverse"}
    definitions = {}
    for path in python_sources():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.FunctionDef) and node.name in names:
                definitions.setdefault(node.name, []).append(str(path.relative_to(REPO)))
    se2 = "src/turtlebot3c_common/src/turtlebot3c_common/se2.py"
    assert definitions == {name: [se2] for name in ("wrap_angle", "yaw_to_quaternion", "quaternion_to_yaw",
                                                    "compose", "inverse")}
