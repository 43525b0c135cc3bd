"""The processes the demo runs beside the snap: roscore, the simulator, the fake robot.

Each is a ros_harness.Process: its own session, its output in a log file, stopped with all
its descendants (roslaunch's children too).
"""
from pathlib import Path

from .ros_harness import Process, master_answers
from .waiting import wait_until


def wait_for_master(uri, timeout=60.0):
    """Until the master at `uri` answers."""
    wait_until(lambda: master_answers(uri), timeout, f"no ROS master answered at {uri}", interval=0.2)


def background(args, log, env):
    Path(log).parent.mkdir(parents=True, exist_ok=True)
    return Process(args, env, log)


def roscore(port, log, env):
    return background(["roscore", "-p", str(port)], log, env)


def simulator(world, model, log, env):
    return background(["roslaunch", "turtlebot3c_sim", "turtlebot3_world.launch", f"world:={world}",
                       f"model:={model}"], log, env)


def fake_robot(folder, world, model, lds_model, log, env):
    """The fake OpenCR and LIDAR on ptys (links in `folder`), with the ground truth on ROS."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    process = background(["rosrun", "turtlebot3c_sim", "fake_robot", "--opencr-link", folder / "ttyACM0",
                          "--lds-link", folder / "ttyUSB0", "--lds-model", lds_model, "--model", model,
                          "--world", world, "--publish-ground-truth"], log, env)
    return process, folder / "ttyACM0", folder / "ttyUSB0"
