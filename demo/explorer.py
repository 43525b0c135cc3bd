"""Drive the robot around a world as a person at the keyboard would, for mapping.

The person sees where the robot is: the explorer steers on the simulator's ground truth.
A tour is a list of steps: a spin in place (to see all around) or a waypoint. The legs
between waypoints are planned on the world's true geometry (turtlebot3c_navigation's planner
on a rasterised world), so the robot keeps clear of obstacles, and followed with pure
pursuit at a gentle speed, so the scans stay easy to match.
"""
import math

import numpy as np

SPIN = "spin"

# Tours of turtlebot3_world (world frame, metres; spawn at (-2.0, -0.5)). The full tour
# goes round the ring of pillars between them and the hexagons, then snakes through the
# lanes between the pillars; the quick one (for the test) sees the world from the lane below them.
TOURS = {
    "turtlebot3_world": {
        "full": [SPIN, (-1.5, -1.55), (0.55, -1.8), (1.7, -1.2), (1.8, 0.0), (1.7, 1.2), (-0.55, 1.8),
                 (-1.5, 1.55), (-2.0, 0.4), (-0.55, 0.55), (0.55, 0.55), (0.55, -0.55), (-0.55, -0.55),
                 (-1.9, -0.6), SPIN],
        "quick": [SPIN, (-1.5, -1.55), (-0.55, -1.8), (0.55, -1.8)],
    },
    # The house (spawn (-2.5, -2.0) in the kitchen): round the loop of the four rooms,
    # kitchen, hall, living room, bedroom, and back, so SLAM has a loop to close.
    "house": {
        "full": [SPIN, (-1.0, -2.0), (1.0, -2.0), (3.5, -1.5), (3.0, -0.7), (3.0, 0.6), (4.2, 1.5), (1.5, 1.5),
                 (1.0, 2.0), (-1.0, 2.0), (-3.5, 1.6), (-3.0, 0.8), (-3.0, -0.8), (-2.5, -2.0), SPIN],
        "quick": [SPIN, (-1.0, -2.0), (1.0, -2.0), (2.5, -2.0), SPIN],
    },
}

# Navigation goals (world frame: x, y, yaw) reached on the saved map after mapping.
GOALS = {
    "turtlebot3_world": {
        "full": [(1.7, -1.2, math.pi / 2), (1.7, 1.2, math.pi), (-1.5, 1.55, -math.pi / 2), (-2.0, -0.5, 0.0)],
        # 0.45 m from the nearest pillar: before scans were deskewed, the real-robot path's turns
        # smeared them into phantom obstacles there and move_base refused it.
        "quick": [(-1.5, -1.55, math.pi)],
    },
    "house": {
        "full": [(3.2, -1.8, 0.0), (4.0, 0.8, math.pi / 2), (-1.2, 1.5, math.pi), (-2.5, -2.0, 0.0)],
        "quick": [(-1.0, -2.0, math.pi)],
    },
}


def tour_for(world_name, length):
    if world_name not in TOURS:
        raise ValueError(f"no tour known for world {world_name!r} (known: {', '.join(sorted(TOURS))})")
    return TOURS[world_name][length], GOALS[world_name][length]


class Spin:
    """Turn once around in place (counter-clockwise), tracking the yaw turned so far."""

    def __init__(self, rate):
        self.rate = rate
        self.turned = 0.0
        self.last_yaw = None

    def command(self, pose):
        from turtlebot3c_common.se2 import wrap_angle  # here, as in plan_tour: `demo/run --help` needs no build

        if self.last_yaw is not None:
            self.turned += wrap_angle(pose[2] - self.last_yaw)
        self.last_yaw = pose[2]
        if self.turned >= 2 * math.pi - 0.1:
            return None
        return 0.0, self.rate


class PurePursuit:
    """Follow a path (N x 2 points): head for the point `lookahead` ahead, turn on the spot
    when it is far to the side; done within `tolerance` of the last point."""

    def __init__(self, path, max_linear, max_angular, lookahead=0.3, tolerance=0.08):
        self.path = np.asarray(path, float)
        self.max_linear = max_linear
        self.max_angular = max_angular
        self.lookahead = lookahead
        self.tolerance = tolerance
        self.progress = 0

    def command(self, pose):
        x, y, yaw = pose
        end = self.path[-1]
        if math.hypot(end[0] - x, end[1] - y) < self.tolerance:
            return None
        # Progress only moves forward, so a path that passes near itself is not cut short.
        window = self.path[self.progress:self.progress + 40]
        self.progress += int(np.argmin(np.hypot(window[:, 0] - x, window[:, 1] - y)))
        ahead = np.hypot(self.path[self.progress:, 0] - x, self.path[self.progress:, 1] - y)
        beyond = np.nonzero(ahead >= self.lookahead)[0]
        target = self.path[self.progress + beyond[0]] if len(beyond) else end
        from turtlebot3c_common.se2 import wrap_angle

        heading_error = wrap_angle(math.atan2(target[1] - y, target[0] - x) - yaw)
        if abs(heading_error) > 0.6:
            return 0.0, math.copysign(0.6 * self.max_angular, heading_error)
        distance = math.hypot(target[0] - x, target[1] - y)
        linear = self.max_linear * (1.0 - abs(heading_error) / 0.6) * min(1.0, distance / self.lookahead + 0.3)
        angular = 2.0 * math.sin(heading_error) / max(distance, 1e-3) * max(linear, 0.05)
        return linear, float(np.clip(angular, -self.max_angular, self.max_angular))


def plan_tour(world, start_xy, steps, robot_radius):
    """The tour's legs: for each step, either SPIN or a path (N x 2) from the previous point."""
    # Imported here so that `demo/run --help` works before anything is built.
    from turtlebot3c_navigation.costmap import Costmap
    from turtlebot3c_navigation.global_planner import GlobalPlanner
    from turtlebot3c_sim.navigation_loop import world_layers

    layers = world_layers(world)
    costmap = Costmap(layers.info, static_occupied=layers.occupied, robot_radius=robot_radius + 0.03,
                      inflation_radius=robot_radius + 0.35, cost_scaling_factor=4.0)
    planner = GlobalPlanner(clearance_radius=0.3)
    legs, here = [], tuple(start_xy)
    for step in steps:
        if step == SPIN:
            legs.append(SPIN)
            continue
        legs.append(planner.plan(costmap, here, step))
        here = tuple(step)
    return legs
