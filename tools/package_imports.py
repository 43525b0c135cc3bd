"""What each catkin package of the workspace uses: the modules its Python imports, the packages
its launch files run or include, and the commands its code runs by name.

Read by check_rosdep.py (each package.xml must list exactly what its package uses) and by
package_graph.py. Plain text and ast only: needs neither ROS nor a build.
"""
import ast
import re
import sys
import sysconfig
from pathlib import Path

# Imports that are rosdep keys of another name (the rest of the third-party imports are ROS
# packages, named as they are imported).
ROSDEP_KEY_OF_MODULE = {
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "yaml": "python3-yaml",
    "serial": "python3-serial",
    "rosbags": "python3-rosbags-pip",
}


def standard_library():
    """Top-level names of the standard library's modules."""
    if hasattr(sys, "stdlib_module_names"):  # Python 3.10 on
        return set(sys.stdlib_module_names)
    # Python 3.8 (the core20 lane runs the check tools' tests): what the standard library's
    # folders hold, and the modules built into the interpreter.
    stdlib = Path(sysconfig.get_paths()["stdlib"])
    folders = [stdlib, stdlib / "lib-dynload"]
    return set(sys.builtin_module_names) | {entry.name.split(".")[0] for folder in folders if folder.is_dir()
                                            for entry in folder.iterdir()}


STANDARD_LIBRARY = standard_library() | {"__future__"}
LAUNCH_PACKAGE = re.compile(r'pkg="([A-Za-z0-9_]+)"|\$\(find ([A-Za-z0-9_]+)\)')
LAUNCH_XACRO = re.compile(r'command="xacro\b')
# Commands the code runs by name (the first word of an argv list), and the package each comes from.
PACKAGE_OF_COMMAND = {"rosbag": "rosbag", "rosrun": "rosbash", "roslaunch": "roslaunch", "rostopic": "rostopic",
                      "xacro": "xacro"}
COMMAND_RUN = re.compile(r'\[\s*"({})"'.format("|".join(PACKAGE_OF_COMMAND)))


def python_files(package_dir):
    """The package's Python: its modules under src/ and its executables under nodes/."""
    return sorted(package_dir.glob("src/**/*.py")) + sorted(path for path in package_dir.glob("nodes/*")
                                                            if path.is_file())


def imported_modules(source, filename):
    """Top-level names of the absolute imports in one Python source."""
    modules = set()
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Import):
            modules.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            modules.add(node.module.split(".")[0])
    return modules


def launch_packages(package_dir):
    """Packages the launch files run nodes of, find, or call (xacro)."""
    used = set()
    for launch in sorted(package_dir.glob("launch/*.launch")):
        text = launch.read_text()
        used.update(first or second for first, second in LAUNCH_PACKAGE.findall(text))
        if LAUNCH_XACRO.search(text):
            used.add("xacro")
    return used


def used_keys(package_dir):
    """{rosdep key or package name: why} for everything the package uses."""
    used = {}
    for path in python_files(package_dir):
        where = path.relative_to(package_dir)
        source = path.read_text()
        for module in imported_modules(source, str(path)) - STANDARD_LIBRARY:
            used.setdefault(ROSDEP_KEY_OF_MODULE.get(module, module), f"imported by {where}")
        for command in COMMAND_RUN.findall(source):
            used.setdefault(PACKAGE_OF_COMMAND[command], f"run by {where}")
    for package in launch_packages(package_dir):
        used.setdefault(package, "in its launch files")
    used.pop(package_dir.name, None)
    used.pop("catkin_pkg", None)  # setup.py's, at build time: catkin (the buildtool) brings it
    return used
