"""nav_msgs/OccupancyGrid to and from the maps' OccupancyMap, as map_server publishes it.

Message classes only, no rospy; times are passed in by the caller.
"""
import numpy as np
from nav_msgs.msg import MapMetaData, OccupancyGrid

from turtlebot3c_common.message_fields import pose_from_msg
from turtlebot3c_common.ros_messages import pose_msg


def map_metadata(occupancy_map, stamp) -> MapMetaData:
    x, y, yaw = occupancy_map.origin
    return MapMetaData(map_load_time=stamp, resolution=occupancy_map.resolution, width=occupancy_map.width,
                       height=occupancy_map.height, origin=pose_msg(x, y, yaw))


def occupancy_grid_msg(occupancy_map, frame_id, stamp) -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = frame_id
    grid.header.stamp = stamp
    grid.info = map_metadata(occupancy_map, stamp)
    grid.data = occupancy_map.grid_message_data()
    return grid


def grid_from_msg(grid):
    """(data (height x width int8), resolution, origin (x, y, yaw)) of an OccupancyGrid."""
    info = grid.info
    data = np.asarray(grid.data, dtype=np.int8).reshape(info.height, info.width)
    return data, info.resolution, pose_from_msg(info.origin)
