"""move_base's logic without ROS: goals, planning, control, recovery, success and abort.

The navigator owns two costmaps: the global one in the map frame (the static map plus
laser obstacles, inflated) on which the global planner plans, and a rolling local one in
the odom frame on which the controller checks its arcs. The controller works in the map
frame; its arcs are carried into the odom frame to be checked, so a localisation jump
never moves an obstacle relative to the robot.

Call `set_goal`, then `update_scan` for each laser scan and `step` at the controller
frequency; `step` returns the velocity command, and `state` / `status_text` tell the
outcome: SUCCEEDED, or ABORTED with the reason (unreachable goal, stuck robot).
"""
import math
from typing import List, NamedTuple, Optional

import numpy as np

from turtlebot3c_common.se2 import compose, inverse, wrap_angle

from .costmap import INSCRIBED, Costmap, RollingCostmap
from .dwa import DwaController
from .global_planner import GlobalPlanner, PlanningError

IDLE = "idle"
ACTIVE = "active"
SUCCEEDED = "succeeded"
ABORTED = "aborted"
PREEMPTED = "preempted"


class NavParams(NamedTuple):
    planner_frequency: float = 1.0
    planner_patience: float = 5.0
    controller_patience: float = 15.0
    oscillation_timeout: float = 10.0
    oscillation_distance: float = 0.2
    conservative_reset_dist: float = 3.0
    recovery_behavior_enabled: bool = True
    backoff_distance: float = 0.15
    backoff_speed: float = 0.08
    rotate_speed: float = 1.0


class _OdomView:
    """The local (odom-frame) costmap seen from the map frame."""

    def __init__(self, costmap: Costmap, odom_from_map):
        self.costmap = costmap
        self.transform = odom_from_map

    def _to_odom(self, x, y):
        tx, ty, tyaw = self.transform
        c, s = math.cos(tyaw), math.sin(tyaw)
        x, y = np.asarray(x), np.asarray(y)
        return tx + c * x - s * y, ty + s * x + c * y

    def cost_at(self, x, y):
        return self.costmap.cost_at(*self._to_odom(x, y))

    def clearance_at(self, x, y):
        return self.costmap.clearance_at(*self._to_odom(x, y))


class _Recovery:
    """One recovery behaviour in progress: a name and a command generator's state."""

    def __init__(self, name, start_pose, start_time):
        self.name = name
        self.start_pose = start_pose
        self.start_time = start_time
        self.turned = 0.0
        self.last_yaw = start_pose[2]


class Navigator:
    def __init__(self, global_costmap: Costmap, local_costmap: RollingCostmap, planner: GlobalPlanner,
                 controller: DwaController, params: Optional[NavParams] = None):
        self.global_costmap = global_costmap
        self.local_costmap = local_costmap
        self.planner = planner
        self.controller = controller
        self.params = params or NavParams()
        self.state = IDLE
        self.status_text = ""
        self.goal = None
        self.plan: Optional[np.ndarray] = None
        self.recoveries_run: List[str] = []
        self._reset_timers(0.0)

    def _reset_timers(self, now):
        self._last_plan_time = -math.inf
        self._last_valid_plan_time = now
        self._last_valid_control_time = now
        self._progress_pose = None
        self._progress_time = now
        self._recovery: Optional[_Recovery] = None
        self._recovery_index = 0

    # --- goals ------------------------------------------------------------------------

    def set_goal(self, goal, now):
        """Start (or replace) navigation to goal (x, y, yaw) in the map frame."""
        self.goal = tuple(float(v) for v in goal)
        self.state = ACTIVE
        self.status_text = "planning to ({:.2f}, {:.2f}, {:.2f})".format(*self.goal)
        self.plan = None
        self.recoveries_run = []
        self._reset_timers(now)
        self.controller.reset()

    def cancel(self, text="goal cancelled"):
        if self.state == ACTIVE:
            self.state = PREEMPTED
            self.status_text = text

    # --- sensing ----------------------------------------------------------------------

    def update_scan(self, pose_map, pose_odom, ranges, angles, range_min=0.12, sensor_offset=(0.0, 0.0, 0.0),
                    range_max=math.inf):
        """Mark and clear both costmaps with a scan taken at these poses."""
        self.global_costmap.update_from_scan(pose_map, ranges, angles, range_min, sensor_offset, range_max)
        self.local_costmap.recenter(pose_odom[0], pose_odom[1])
        self.local_costmap.update_from_scan(pose_odom, ranges, angles, range_min, sensor_offset, range_max)

    # --- control ----------------------------------------------------------------------

    def step(self, now, pose_map, pose_odom, velocity):
        """One control period: returns (linear, angular) and updates state/status_text."""
        if self.state != ACTIVE:
            return 0.0, 0.0
        if self._recovery is not None:
            return self._run_recovery(now, pose_map)
        if self._plan_due(now, pose_map):
            if not self._replan(now, pose_map):
                return self._handle_planning_failure(now, pose_map)
        if self.plan is None:
            return 0.0, 0.0
        odom_from_map = compose(pose_odom, inverse(pose_map))
        command = self.controller.compute(pose_map, velocity, _OdomView(self.local_costmap, odom_from_map))
        if command.status == "arrived":
            self.state = SUCCEEDED
            self.status_text = "goal reached"
            return 0.0, 0.0
        if command.status == "blocked":
            self._last_plan_time = -math.inf  # replan around what blocks us next period
            if now - self._last_valid_control_time > min(self.params.controller_patience, 1.0):
                return self._start_recovery(now, pose_map, "no safe motion towards the plan")
            return 0.0, 0.0
        self._last_valid_control_time = now
        if self._oscillating(now, pose_map):
            return self._start_recovery(now, pose_map, f"no progress for {self.params.oscillation_timeout:.0f} s")
        return command.linear, command.angular

    def _plan_due(self, now, pose_map):
        if self.plan is None or now - self._last_plan_time >= 1.0 / self.params.planner_frequency:
            return True
        return self._plan_blocked(pose_map)

    def _plan_blocked(self, pose_map):
        """True when the part of the plan ahead of the robot now crosses an obstacle."""
        ahead = self.plan[self.controller._progress_index:]
        if len(ahead) == 0:
            return False
        costs = self.global_costmap.cost_at(ahead[:, 0], ahead[:, 1])
        far_enough = np.hypot(ahead[:, 0] - pose_map[0], ahead[:, 1] - pose_map[1]) > self.global_costmap.robot_radius
        return bool(np.any((costs >= INSCRIBED) & far_enough))

    def _replan(self, now, pose_map) -> bool:
        self._last_plan_time = now
        try:
            plan = self.planner.plan(self.global_costmap, pose_map[:2], self.goal[:2])
        except PlanningError as error:
            self._planning_error = str(error)
            return False
        self.plan = plan
        self.controller.set_plan(plan, self.goal)
        self._last_valid_plan_time = now
        self.status_text = f"following a {_length(plan):.2f} m plan"
        return True

    def _handle_planning_failure(self, now, pose_map):
        if self._static_map_blocks(pose_map):
            return self._abort("goal unreachable: " + self._planning_error)
        if now - self._last_valid_plan_time < self.params.planner_patience:
            self.plan = None
            return 0.0, 0.0
        return self._start_recovery(now, pose_map, self._planning_error)

    def _static_map_blocks(self, pose_map) -> bool:
        """Would planning fail even with no laser obstacles? Then waiting cannot help."""
        if not self.global_costmap.obstacles.any():
            return True
        saved = self.global_costmap.obstacles.copy()
        self.global_costmap.clear_obstacles()
        try:
            self.planner.plan(self.global_costmap, pose_map[:2], self.goal[:2])
            blocked = False
        except PlanningError:
            blocked = True
        self.global_costmap.obstacles = saved
        self.global_costmap._costs = None
        return blocked

    def _oscillating(self, now, pose_map):
        if self._progress_pose is None or math.hypot(pose_map[0] - self._progress_pose[0],
                                                     pose_map[1] - self._progress_pose[1]) > \
                self.params.oscillation_distance:
            self._progress_pose = pose_map
            self._progress_time = now
            return False
        # Turning on the spot to the final heading is progress too.
        if self.controller.xy_reached:
            self._progress_time = now
            return False
        return now - self._progress_time > self.params.oscillation_timeout

    # --- recovery ---------------------------------------------------------------------

    RECOVERIES = ("clear_costmaps", "rotate", "back_off")

    def _start_recovery(self, now, pose_map, reason):
        if not self.params.recovery_behavior_enabled or self._recovery_index >= len(self.RECOVERIES):
            return self._abort("aborted after recovery behaviours: " + reason)
        name = self.RECOVERIES[self._recovery_index]
        self._recovery_index += 1
        self.recoveries_run.append(name)
        self.status_text = f"recovering ({name}): {reason}"
        self._recovery = _Recovery(name, pose_map, now)
        return self._run_recovery(now, pose_map)

    def _run_recovery(self, now, pose_map):
        recovery = self._recovery
        done = False
        command = (0.0, 0.0)
        if recovery.name == "clear_costmaps":
            self.global_costmap.clear_obstacles_outside(pose_map[0], pose_map[1], self.params.conservative_reset_dist)
            self.local_costmap.clear_obstacles()
            done = True
        elif recovery.name == "rotate":
            recovery.turned += abs(wrap_angle(pose_map[2] - recovery.last_yaw))
            recovery.last_yaw = pose_map[2]
            done = recovery.turned >= 2.0 * math.pi - 0.2 or now - recovery.start_time > 15.0
            command = (0.0, self.params.rotate_speed)
        elif recovery.name == "back_off":
            moved = math.hypot(pose_map[0] - recovery.start_pose[0], pose_map[1] - recovery.start_pose[1])
            done = moved >= self.params.backoff_distance or now - recovery.start_time > 5.0 \
                or not self._rear_clear(pose_map)
            command = (-self.params.backoff_speed, 0.0)
        if done:
            self._recovery = None
            self._last_plan_time = -math.inf
            self._last_valid_plan_time = now
            self._last_valid_control_time = now
            self._progress_pose, self._progress_time = pose_map, now
            return 0.0, 0.0
        return command

    def _rear_clear(self, pose_map):
        x, y, yaw = pose_map
        back = self.global_costmap.robot_radius + 0.05
        cost = self.global_costmap.cost_at(np.array([x - back * math.cos(yaw)]), np.array([y - back * math.sin(yaw)]))
        return bool(cost[0] < INSCRIBED)

    def _abort(self, text):
        self.state = ABORTED
        self.status_text = text
        self._recovery = None
        return 0.0, 0.0


def _length(points):
    return float(np.hypot(*np.diff(points, axis=0).T).sum()) if len(points) > 1 else 0.0
