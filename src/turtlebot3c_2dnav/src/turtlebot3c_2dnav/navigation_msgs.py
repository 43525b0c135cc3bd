"""Conversions between ROS messages and the plain values the navigation modules use.

Message classes only (geometry_msgs, nav_msgs): no rospy, so the conversions are tested
without a ROS master. Times are passed in by the caller.
"""
import math

import numpy as np
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, TransformStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid, Path

from .costmap import INSCRIBED, LETHAL, NO_INFORMATION
from .geometry import quaternion_to_yaw, yaw_to_quaternion


def pose_msg(x, y, yaw) -> Pose:
    return Pose(position=Point(x, y, 0.0), orientation=Quaternion(*yaw_to_quaternion(yaw)))


def pose_from_msg(pose) -> tuple:
    """(x, y, yaw) of a geometry_msgs/Pose."""
    q = pose.orientation
    return (pose.position.x, pose.position.y, quaternion_to_yaw(q.x, q.y, q.z, q.w))


def pose_from_transform(transform) -> tuple:
    """(x, y, yaw) of a geometry_msgs/Transform."""
    t, q = transform.translation, transform.rotation
    return (t.x, t.y, quaternion_to_yaw(q.x, q.y, q.z, q.w))


def transform_msg(pose, parent, child, stamp) -> TransformStamped:
    message = TransformStamped()
    message.header.stamp = stamp
    message.header.frame_id = parent
    message.child_frame_id = child
    message.transform.translation.x, message.transform.translation.y = pose[0], pose[1]
    message.transform.rotation = Quaternion(*yaw_to_quaternion(pose[2]))
    return message


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


def costs_to_occupancy(costs) -> np.ndarray:
    """costmap_2d's display mapping of costs to occupancy values: 0..252 scaled to 1..98,
    INSCRIBED 99, LETHAL 100, NO_INFORMATION -1, free 0."""
    costs = np.asarray(costs)
    values = np.where(costs == 0, 0, 1 + (97 * costs.astype(np.int32)) // 251).astype(np.int8)
    values[costs == INSCRIBED] = 99
    values[costs == LETHAL] = 100
    values[costs == NO_INFORMATION] = -1
    return values


def costmap_msg(costmap, frame_id, stamp) -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = frame_id
    grid.header.stamp = stamp
    info = costmap.info
    grid.info = MapMetaData(map_load_time=stamp, resolution=info.resolution, width=info.width, height=info.height,
                            origin=pose_msg(info.origin_x, info.origin_y, 0.0))
    grid.data = costs_to_occupancy(costmap.costs).ravel().tolist()
    return grid


def path_msg(points, frame_id, stamp) -> Path:
    """A nav_msgs/Path through points (N x 2), each pose facing along the path."""
    path = Path()
    path.header.frame_id = frame_id
    path.header.stamp = stamp
    points = np.asarray(points, dtype=float)
    for index, (x, y) in enumerate(points):
        following = points[min(index + 1, len(points) - 1)]
        previous = points[max(index - 1, 0)]
        yaw = math.atan2(following[1] - previous[1], following[0] - previous[0]) if len(points) > 1 else 0.0
        stamped = PoseStamped()
        stamped.header = path.header
        stamped.pose = pose_msg(float(x), float(y), yaw)
        path.poses.append(stamped)
    return path
