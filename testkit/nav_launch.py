"""The navigation stack through roslaunch, for the navigation launch tests: from the install space,
the simulator, the model (bringup simulation:=true), the teleop mux and turtlebot3c_navigation.launch
on a map of turtlebot3_world, with the robot localised at its spawn pose."""
import math

import numpy as np

from turtlebot3c_maps.map_files import OccupancyMap, save_map
from turtlebot3c_sim.navigation_loop import world_layers
from turtlebot3c_sim.world import load_world

RESULT = "move_base_msgs/MoveBaseActionResult"
GROUND_TRUTH = "nav_msgs/Odometry"
SUCCEEDED, ABORTED = 3, 4
SPAWN = (-2.0, -0.5, 0.0)


def write_world_map(folder):
    layers = world_layers(load_world("turtlebot3_world"))
    data = np.where(layers.occupied, 100, 0)
    folder.mkdir(parents=True, exist_ok=True)
    yaml_path, _ = save_map(OccupancyMap(data, layers.info.resolution, (layers.info.origin_x, layers.info.origin_y, 0)),
                            folder / "current_map")
    return yaml_path


def launch_simulated_robot(master, world_file=None):
    """The simulator (in `world_file` if given, else turtlebot3_world), the burger's bringup
    (simulation:=true) and the teleop mux on `master`: a robot for the mapping and navigation launches."""
    world = [f"world:={world_file}"] if world_file else []
    master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "model:=burger", *world)
    master.launch("turtlebot3c_bringup", "turtlebot3c_bringup.launch", "simulation:=true", "model:=burger")
    master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")


def launch_navigation(master, world_file=None):
    """Launch it all on `master`, the simulator in `world_file` if given; navigation always gets
    turtlebot3_world's map, so whatever `world_file` adds is missing from the map."""
    map_file = write_world_map(master.workdir / "map")
    launch_simulated_robot(master, world_file)
    master.launch("turtlebot3c_navigation", "turtlebot3c_navigation.launch", "model:=burger", f"map_file:={map_file}",
                  f"initial_pose_x:={SPAWN[0]}", f"initial_pose_y:={SPAWN[1]}", f"initial_pose_a:={SPAWN[2]}")
    for node in ("/map_server", "/amcl", "/move_base", "/mux", "/simulator"):
        master.wait_for_node(node, timeout=90)
    master.probe.wait_for_message("/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped", timeout=60, start=0)
    return master


def pose_stamped(x, y, yaw):
    return {"header": {"frame_id": "map"},
            "pose": {"position": {"x": x, "y": y}, "orientation": {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}}}


def true_pose(probe, timeout=10):
    message = probe.wait_for_message("/sim/ground_truth", GROUND_TRUTH, timeout=timeout)
    pose = message["pose"]["pose"]
    yaw = 2 * math.atan2(pose["orientation"]["z"], pose["orientation"]["w"])
    return pose["position"]["x"], pose["position"]["y"], yaw
