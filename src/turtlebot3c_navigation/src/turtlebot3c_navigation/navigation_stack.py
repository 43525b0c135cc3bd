"""Assembly of the navigation pieces from a map and a robot model, shared by the ROS
nodes, the closed-loop simulations of the tests and the benchmark.

Maps arrive as occupancy values (nav_msgs/OccupancyGrid semantics: -1 unknown, 0..100);
cells at or above `occupied_value` are obstacles, unknown cells are neither free space
for localisation nor passable for planning.
"""
import math
from typing import NamedTuple, Optional

import numpy as np

from turtlebot3c_common.parameter_files import like_default
from turtlebot3c_common.se2 import compose, inverse, wrap_angle

from .amcl import AmclParams, ParticleFilter, params_from_dict
from .costmap import Costmap, RollingCostmap, footprint_radii
from .dwa import DwaController, DwaParams, dwa_params_for_model
from .global_planner import GlobalPlanner
from .grid_info import GridInfo
from .navigation import Navigator, NavParams


def scan_offset(model):
    """The laser's planar pose (x, y, yaw) in base_footprint; the ROS nodes read it from tf instead."""
    return (model.scan_mount[0], model.scan_mount[1], 0.0)


class MapLayers(NamedTuple):
    info: GridInfo
    occupied: np.ndarray
    free: np.ndarray
    unknown: np.ndarray


def axis_aligned(data, resolution, origin, samples=3):
    """(data, origin) of a grid turned by its origin's yaw (origin (x, y[, yaw]); as map_server
    places it: the grid rotated about the corner of cell (0, 0)) resampled onto an unrotated
    grid of the same resolution that covers it. Each new cell takes the highest value found at samples x
    samples points spread over it, so no obstacle cell is lost between the two lattices (an
    obstacle may grow by up to a cell); cells wholly outside the turned grid are unknown (-1).
    A grid with no yaw comes back as it is."""
    data = np.asarray(data)
    x0, y0 = float(origin[0]), float(origin[1])
    yaw = float(origin[2]) if len(origin) > 2 else 0.0
    if abs(wrap_angle(yaw)) < 1e-9:
        return data, (x0, y0, 0.0)
    height, width = data.shape
    c, s = math.cos(yaw), math.sin(yaw)
    corners = np.array([[0.0, 0.0], [width, 0.0], [0.0, height], [width, height]]) * resolution
    xs, ys = x0 + c * corners[:, 0] - s * corners[:, 1], y0 + s * corners[:, 0] + c * corners[:, 1]
    new_width = int(math.ceil((xs.max() - xs.min()) / resolution - 1e-6))
    new_height = int(math.ceil((ys.max() - ys.min()) / resolution - 1e-6))
    resampled = np.full((new_height, new_width), -1, dtype=np.result_type(data.dtype, np.int8))
    offsets = (np.arange(samples) + 0.5) / samples
    for fx in offsets:
        for fy in offsets:
            dx = xs.min() + (np.arange(new_width)[None, :] + fx) * resolution - x0
            dy = ys.min() + (np.arange(new_height)[:, None] + fy) * resolution - y0
            col = np.floor((c * dx + s * dy) / resolution).astype(int)
            row = np.floor((-s * dx + c * dy) / resolution).astype(int)
            inside = (row >= 0) & (row < height) & (col >= 0) & (col < width)
            resampled[inside] = np.maximum(resampled[inside], data[row[inside], col[inside]])
    return resampled, (float(xs.min()), float(ys.min()), 0.0)


def map_layers(data, resolution, origin, occupied_value=65, free_value=25) -> MapLayers:
    """Occupied / free / unknown bool grids of occupancy values (rows = y index); a map whose
    origin has a yaw is first resampled onto an unrotated grid (axis_aligned)."""
    data, origin = axis_aligned(data, resolution, origin)
    info = GridInfo(float(resolution), data.shape[1], data.shape[0], float(origin[0]), float(origin[1]))
    unknown = data < 0
    occupied = data >= occupied_value
    free = (data >= 0) & (data <= free_value)
    return MapLayers(info, occupied, free, unknown)


def layers_from_occupied(occupied, resolution, origin) -> MapLayers:
    """Layers of a bool grid with no unknown cells (e.g. a rasterised simulator world)."""
    occupied = np.asarray(occupied, dtype=bool)
    return map_layers(np.where(occupied, 100, 0), resolution, origin)


class CostmapParams(NamedTuple):
    robot_radius: float = 0.105
    safety_margin: float = 0.03
    inflation_radius: float = 1.0
    cost_scaling_factor: float = 3.0
    obstacle_range: float = 3.0
    raytrace_range: float = 3.5
    local_size: float = 3.0
    local_resolution: float = 0.05


def costmap_params_for_model(model, **overrides) -> CostmapParams:
    """The robot as the circle its footprint sweeps when it turns on the spot."""
    _, circumscribed = footprint_radii(model.footprint)
    return CostmapParams(robot_radius=circumscribed)._replace(**overrides)


class MoveBaseConfig(NamedTuple):
    costmap: CostmapParams
    dwa: DwaParams
    nav: NavParams
    cost_weight: float


def _override(defaults, values, section=""):
    """`defaults` (a NamedTuple) with the fields found in the mapping `values`, each of the
    default's type (ValueError otherwise); other keys (frames, other sections) are not this
    tuple's business."""
    found = {name: like_default(values[name], getattr(defaults, name), f"move_base parameter {section}{name}")
             for name in defaults._fields if name in values}
    return defaults._replace(**found)


def move_base_config(values, model) -> MoveBaseConfig:
    """move_base's settings from its parameters (config/move_base_<model>.yaml as a dict:
    move_base's own keys at the top, then costmap:, planner:, DWAPlannerROS: sections),
    on top of the model's defaults. Speeds never exceed what the model's firmware allows."""
    dwa = _override(dwa_params_for_model(model), values.get("DWAPlannerROS") or {}, "DWAPlannerROS/")
    frequency = like_default(values.get("controller_frequency", dwa.controller_frequency), dwa.controller_frequency,
                             "move_base parameter controller_frequency")
    dwa = dwa._replace(controller_frequency=frequency,
                       max_vel_x=min(dwa.max_vel_x, model.max_linear_velocity),
                       min_vel_x=max(dwa.min_vel_x, -model.max_linear_velocity),
                       max_vel_theta=min(dwa.max_vel_theta, model.max_angular_velocity))
    return MoveBaseConfig(
        costmap=_override(costmap_params_for_model(model), values.get("costmap") or {}, "costmap/"),
        dwa=dwa,
        nav=_override(NavParams(), values),
        cost_weight=like_default((values.get("planner") or {}).get("cost_weight", 1.0), 1.0,
                                 "move_base parameter planner/cost_weight"))


def amcl_params(values) -> AmclParams:
    """The particle filter's settings among amcl's parameters (config/amcl.yaml as a dict)."""
    return params_from_dict({name: value for name, value in values.items() if name in AmclParams._fields})


def make_costmaps(layers: MapLayers, params: CostmapParams):
    radius = params.robot_radius + params.safety_margin
    common = dict(robot_radius=radius, inflation_radius=params.inflation_radius,
                  cost_scaling_factor=params.cost_scaling_factor, obstacle_range=params.obstacle_range,
                  raytrace_range=params.raytrace_range)
    global_costmap = Costmap(layers.info, layers.occupied, layers.unknown, **common)
    local_costmap = RollingCostmap(size=params.local_size, resolution=params.local_resolution, **common)
    return global_costmap, local_costmap


def make_navigator(layers: MapLayers, model, costmap_params: CostmapParams = None, dwa_params: DwaParams = None,
                   nav_params: Optional[NavParams] = None, cost_weight=1.0) -> Navigator:
    costmap_params = costmap_params or costmap_params_for_model(model)
    dwa_params = dwa_params or dwa_params_for_model(model)
    global_costmap, local_costmap = make_costmaps(layers, costmap_params)
    return Navigator(global_costmap, local_costmap, GlobalPlanner(cost_weight=cost_weight),
                     DwaController(dwa_params), nav_params)


def make_filter(layers: MapLayers, params: Optional[AmclParams] = None, seed=None) -> ParticleFilter:
    return ParticleFilter(layers.occupied, layers.info, free=layers.free, params=params, seed=seed)


class Localizer:
    """The particle filter plus the map→odom correction it implies (what amcl publishes)."""

    def __init__(self, particle_filter: ParticleFilter):
        self.filter = particle_filter
        self.map_from_odom = (0.0, 0.0, 0.0)

    def set_pose(self, pose_map, odom, covariance=None):
        self.filter.set_pose(pose_map, covariance)
        self.filter.last_odom = None
        self.map_from_odom = compose(pose_map, inverse(odom))

    def global_localization(self):
        self.filter.global_localization()
        self.filter.last_odom = None

    def update(self, odom, ranges, angles, range_min, sensor_offset, range_max=math.inf) -> bool:
        ran = self.filter.update(odom, ranges, angles, range_min, sensor_offset, range_max)
        if ran and self.filter.estimate is not None:
            self.map_from_odom = compose(self.filter.estimate.pose, inverse(odom))
        return ran

    def pose(self, odom):
        """Robot pose in the map given its odometry pose now."""
        return compose(self.map_from_odom, odom)


def scan_angles(scan):
    """Each beam's angle (rad) in a sensor_msgs/LaserScan's frame."""
    return scan.angle_min + np.arange(len(scan.ranges)) * scan.angle_increment


def pose_error(estimate, truth):
    """(position error m, heading error rad) between two poses."""
    return (math.hypot(estimate[0] - truth[0], estimate[1] - truth[1]),
            abs(wrap_angle(estimate[2] - truth[2])))
