"""Closed-loop navigation against a stepping simulator, without ROS: what the nodes do,
in simulated time, for tests and the benchmark.

The simulator is duck-typed (turtlebot3c_sim.simulation.Simulation's API): set_command,
step(dt), time, pose (ground truth), velocity, odometry, collided, scan(). Scans arrive
at scan_period, the controller runs at the navigator's controller frequency; each scan
updates the particle filter and both costmaps, as the amcl and move_base nodes do.
"""
import math
from typing import List, NamedTuple, Optional

import numpy as np

from turtlebot3c_description.models import get_model
from turtlebot3c_navigation.amcl import AmclParams
from turtlebot3c_navigation.navigation import ACTIVE
from turtlebot3c_navigation.navigation_stack import (
    Localizer,
    MapLayers,
    layers_from_occupied,
    make_filter,
    make_navigator,
    pose_error,
    scan_angles,
    scan_offset,
)

from .simulation import Simulation
from .world import load_world


def world_layers(world, resolution=0.05) -> MapLayers:
    """A map of a simulator world (its rasterisation over the world's bounds).

    The grid is offset by half a cell, so that cell centres lie on multiples of the
    resolution, where the worlds' walls do: the cells centred on a wall's surface are
    occupied, on whichever side the wall faces. With cell edges there instead, every
    surface would be drawn a fraction of a cell towards the same side, and localisation
    on the map would be off by that much."""
    xmin, ymin, xmax, ymax = world.bounds
    xmin -= resolution / 2.0
    ymin -= resolution / 2.0
    width = int(np.ceil((xmax - xmin) / resolution))
    height = int(np.ceil((ymax - ymin) / resolution))
    occupied = world.rasterize(resolution, (xmin, ymin), width, height)
    return layers_from_occupied(occupied, resolution, (xmin, ymin))


class GoalResult(NamedTuple):
    state: str
    status_text: str
    duration: float  # simulated seconds
    distance_travelled: float
    collided: bool
    recoveries: List[str]


class ClosedLoop:
    def __init__(self, sim, navigator, localizer: Optional[Localizer], sensor_offset=(0.0, 0.0, 0.0),
                 sim_step=0.02, scan_period=0.2, shadow_localizer: Optional[Localizer] = None):
        """With localizer None the robot knows its true pose (to test planning and control alone);
        a shadow localizer gets the same scans and odometry but does not steer."""
        self.sim = sim
        self.navigator = navigator
        self.localizer = localizer
        self.shadow_localizer = shadow_localizer
        self.sensor_offset = sensor_offset
        self.sim_step = sim_step
        self.scan_period = scan_period
        self.control_period = 1.0 / navigator.controller.params.controller_frequency
        self._next_scan = sim.time
        self._next_control = sim.time
        self.position_errors: List[float] = []
        self.heading_errors: List[float] = []
        self.obstacle_hook = None  # called with the loop each step (tests add obstacles)

    def odom_pose(self):
        odom = self.sim.odometry
        return (odom[0], odom[1], odom[2])

    def estimated_pose(self):
        if self.localizer is None:
            return self.sim.pose
        return self.localizer.pose(self.odom_pose())

    def _on_scan(self):
        scan = self.sim.scan()
        angles = scan_angles(scan)
        odom = self.odom_pose()
        for localizer in (self.localizer, self.shadow_localizer):
            if localizer is not None:
                localizer.update(odom, scan.ranges, angles, scan.range_min, self.sensor_offset, scan.range_max)
        self.navigator.update_scan(self.estimated_pose(), odom, scan.ranges, angles, scan.range_min,
                                   self.sensor_offset, scan.range_max)

    def advance(self, seconds, command=None):
        """Run the scans (and the filter) for `seconds`, driving `command` if given, without navigating."""
        end = self.sim.time + seconds
        while self.sim.time < end - 1e-9:
            if command is not None:
                self.sim.set_command(*command)
            self._tick(navigate=False)

    def _tick(self, navigate=True):
        now = self.sim.time
        if now >= self._next_scan - 1e-9:
            self._on_scan()
            self._next_scan += self.scan_period
        if navigate and now >= self._next_control - 1e-9:
            self._next_control += self.control_period
            estimate = self.estimated_pose()
            linear, angular = self.navigator.step(now, estimate, self.odom_pose(), self.sim.velocity)
            self.sim.set_command(linear, angular)
            error = pose_error(estimate, self.sim.pose)
            self.position_errors.append(error[0])
            self.heading_errors.append(error[1])
        if self.obstacle_hook is not None:
            self.obstacle_hook(self)
        self.sim.step(self.sim_step)

    def run_to_goal(self, goal, timeout=120.0) -> GoalResult:
        """Navigate to goal (x, y, yaw) in the map frame until it succeeds, aborts or times out."""
        start_time = self.sim.time
        self.navigator.set_goal(goal, start_time)
        self._next_control = start_time
        travelled = 0.0
        last = self.sim.pose
        collided = False
        while self.navigator.state == ACTIVE and self.sim.time - start_time < timeout:
            self._tick()
            pose = self.sim.pose
            travelled += math.hypot(pose[0] - last[0], pose[1] - last[1])
            last = pose
            collided = collided or bool(self.sim.collided)
        self.sim.set_command(0.0, 0.0)
        state = self.navigator.state
        text = self.navigator.status_text
        if state == ACTIVE:
            self.navigator.cancel(f"timed out after {timeout:.0f} s")
            state, text = "timeout", self.navigator.status_text
        return GoalResult(state, text, self.sim.time - start_time, travelled, collided,
                          list(self.navigator.recoveries_run))


def closed_loop(world_name="turtlebot3_world", model_name="burger", seed=0, start=None, dwa_params=None):
    """Robot at `start` (default: the world's spawn pose), localised there, on a perfect map of the world."""
    world = load_world(world_name)
    layers = world_layers(world)
    model = get_model(model_name)
    sim = Simulation(world, model_name, pose=start or world.spawn_pose, seed=seed)
    localizer = Localizer(make_filter(layers, AmclParams(), seed=seed))
    localizer.set_pose(sim.pose, sim.odometry[:3])
    return ClosedLoop(sim, make_navigator(layers, model, dwa_params=dwa_params), localizer, scan_offset(model))
