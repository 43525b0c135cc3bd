"""Local control: a dynamic-window controller that follows the global plan.

Each control period it samples (v, w) pairs reachable within one period under the
acceleration limits, rolls each out as an arc for sim_time seconds, drops the arcs that
would bring the robot into an inscribed or lethal costmap cell, and picks the arc whose
end is closest to a carrot point on the plan (lookahead ahead of the robot), close to
the plan itself, well oriented towards the carrot, and far from obstacles.

Around that core: the robot turns on the spot first when the plan starts behind it;
near the goal the carrot is the goal and the speed falls with the distance left so it
stops within xy_goal_tolerance; once there it turns on the spot to the goal heading
(the position is latched, as upstream's latch_xy_goal_tolerance).

With min_vel_x < 0 (turtlebot3_navigation's default; its move_forward_only sets it to 0)
the robot may drive a goal's whole plan backwards, chosen from rest when that needs less
turning on the spot, onto the plan and to the goal heading at its end. Driving backwards
is driving forwards with the robot's heading turned half a turn, which is how it is
computed: the checks against the costmap use the circle the footprint sweeps, the same
either way, and the LIDAR sees all round.
"""
import math
from typing import NamedTuple, Optional

import numpy as np

from turtlebot3c_common.se2 import wrap_angle

from .costmap import INSCRIBED


class DwaParams(NamedTuple):
    max_vel_x: float = 0.22
    min_vel_x: float = -0.22  # m/s; below zero the robot may drive backwards at up to this speed
    max_vel_theta: float = 2.75
    min_in_place_vel_theta: float = 0.4
    acc_lim_x: float = 2.5
    acc_lim_theta: float = 3.2
    sim_time: float = 1.5
    sim_granularity: float = 0.1
    vx_samples: int = 20
    vth_samples: int = 40
    controller_frequency: float = 10.0
    path_distance_bias: float = 1.0
    goal_distance_bias: float = 2.0
    heading_bias: float = 0.3
    occdist_scale: float = 0.3
    lookahead: float = 0.5
    rotate_in_place_threshold: float = 0.9  # rad of heading error to the carrot
    turn_braking: float = 0.6  # share of acc_lim_theta planned for braking turns on the spot
    approach_deceleration: float = 1.0  # m/s^2: the braking profile towards the goal
    min_approach_vel: float = 0.03
    approach_time_weight: float = 0.05  # m of goal distance worth one second sooner
    escape_clearance: float = 0.125  # m, nearest obstacle to the centre on arcs leaving the band
    xy_goal_tolerance: float = 0.05
    yaw_goal_tolerance: float = 0.17
    reverse_saving: float = 0.5  # rad: backwards only when it spares at least this much turning


def dwa_params_for_model(model, **overrides) -> DwaParams:
    """Limits of a turtlebot3c_description RobotModel, with optional overrides."""
    half_width = max(abs(y) for _, y in model.footprint)
    params = DwaParams(max_vel_x=model.max_linear_velocity, min_vel_x=-model.max_linear_velocity,
                       max_vel_theta=model.max_angular_velocity,
                       acc_lim_x=model.max_linear_acceleration, acc_lim_theta=model.max_angular_acceleration,
                       escape_clearance=half_width + 0.02)
    return params._replace(**overrides)


class Command(NamedTuple):
    linear: float
    angular: float
    status: str  # "follow", "rotate", "approach", "align", "arrived", "blocked"


class DwaController:
    def __init__(self, params: Optional[DwaParams] = None):
        self.params = params or DwaParams()
        self.plan: Optional[np.ndarray] = None
        self._progress_index = 0
        self.last_trajectory: Optional[np.ndarray] = None
        self.reset()

    def reset(self):
        """Forget the goal: the next plan is for a new one."""
        self.goal = None
        self.xy_reached = False
        self.direction = 0  # +1 forwards, -1 backwards, 0 not chosen yet
        self._last_distance = math.inf

    def set_plan(self, plan, goal):
        """A new plan (N x 2, in the frame of the poses given to compute) towards goal (x, y, yaw)."""
        if self.goal is None or any(abs(a - b) > 1e-9 for a, b in zip(goal, self.goal)):
            self.reset()
        self.plan = np.asarray(plan, dtype=float)
        self.goal = tuple(goal)
        self._progress_index = 0

    def compute(self, pose, velocity, costmap) -> Command:
        """Velocity command for robot `pose` (x, y, yaw) moving at `velocity` (v, w)."""
        p = self.params
        x, y, yaw = pose
        gx, gy, gyaw = self.goal
        distance = math.hypot(gx - x, gy - y)
        # Stop well inside the tolerance, or as soon as the robot, inside it, starts to pass the goal.
        passing = distance > self._last_distance and distance <= p.xy_goal_tolerance
        self._last_distance = distance
        if distance <= 0.6 * p.xy_goal_tolerance or passing:
            self.xy_reached = True
        if self.xy_reached:
            return self._align(wrap_angle(gyaw - yaw), velocity)
        if not self.direction:
            self.direction = self._driving_direction(yaw, velocity[0])
        # Backwards is forwards for a robot facing the other way.
        sign = self.direction
        driving_pose = (x, y, yaw if sign > 0 else wrap_angle(yaw + math.pi))
        command = self._follow(driving_pose, (sign * velocity[0], velocity[1]), distance, costmap)
        return command._replace(linear=sign * command.linear)

    def _driving_direction(self, yaw, linear):
        """+1 to drive the plan forwards, -1 backwards: already moving, the way the robot
        moves; from rest, backwards when allowed and sparing reverse_saving of turning on the
        spot, onto the plan now and from its end to the goal heading."""
        p = self.params
        if abs(linear) > 0.05:
            return 1 if linear > 0 else -1
        if p.min_vel_x >= 0.0:
            return 1
        onto_plan = self._plan_direction() - yaw
        to_goal_heading = self.goal[2] - self._plan_end_direction()

        def turning(heading_offset):
            return abs(wrap_angle(onto_plan - heading_offset)) + abs(wrap_angle(to_goal_heading - heading_offset))
        return -1 if turning(math.pi) + p.reverse_saving <= turning(0.0) else 1

    def _top_speed(self):
        return self.params.max_vel_x if self.direction > 0 else -self.params.min_vel_x

    def _follow(self, pose, velocity, distance, costmap) -> Command:
        """Follow the plan, driving forwards from `pose` at `velocity`."""
        p = self.params
        x, y, yaw = pose
        carrot, near_goal = self._carrot(x, y)
        heading_error = wrap_angle(math.atan2(carrot[1] - y, carrot[0] - x) - yaw)
        if abs(heading_error) > p.rotate_in_place_threshold and abs(velocity[0]) < 0.05:
            return self._turn(heading_error, velocity, "rotate")
        command = self._best_arc(pose, velocity, carrot, near_goal, distance, costmap)
        if command.status == "follow" and abs(command.linear) < 0.01 and abs(velocity[0]) < 0.01:
            # Only turning on the spot is safe, and no turn brings the carrot closer: face the
            # plan's own direction here (it bends round what is in the way), then go on.
            tangent_error = wrap_angle(self._plan_direction() - yaw)
            if abs(tangent_error) > 0.1:
                return self._turn(tangent_error, velocity, "rotate")
            return Command(0.0, 0.0, "blocked")
        return command

    def _plan_direction(self):
        """Heading of the plan from the robot's nearest plan point to 0.2 m further on."""
        plan = self.plan
        here = plan[self._progress_index]
        ahead = plan[min(len(plan) - 1, self._progress_index + 4)]
        if np.allclose(here, ahead):
            ahead = plan[-1]
        return math.atan2(ahead[1] - here[1], ahead[0] - here[0])

    def _plan_end_direction(self):
        """Heading of the plan over its last 0.2 m: the robot's heading when it arrives."""
        before, end = self.plan[max(0, len(self.plan) - 5)], self.plan[-1]
        if np.allclose(before, end):
            return self.goal[2]
        return math.atan2(end[1] - before[1], end[0] - before[0])

    # --- pieces -----------------------------------------------------------------------

    def _carrot(self, x, y):
        """The point lookahead metres along the plan past the robot's nearest plan point."""
        plan = self.plan
        window = plan[self._progress_index:self._progress_index + 60]
        nearest = self._progress_index + int(np.argmin(np.hypot(window[:, 0] - x, window[:, 1] - y)))
        self._progress_index = nearest
        steps = np.hypot(*np.diff(plan[nearest:], axis=0).T) if len(plan) - nearest > 1 else np.zeros(0)
        along = np.concatenate([[0.0], np.cumsum(steps)])
        ahead = int(np.searchsorted(along, self.params.lookahead))
        if ahead >= len(along):
            return plan[-1], True
        return plan[nearest + ahead], False

    def _turn(self, error, velocity, status):
        """Turn on the spot towards `error` as fast as the limits allow: the speed from which
        braking at turn_braking of the acceleration limit (room for the control period's lag)
        stops the robot on the target heading."""
        p = self.params
        braking = math.sqrt(2.0 * p.acc_lim_theta * p.turn_braking * abs(error))
        speed = min(p.max_vel_theta, max(p.min_in_place_vel_theta, braking))
        return Command(0.0, math.copysign(speed, error), status)

    def _align(self, error, velocity):
        """Turn to the goal heading; arrived once the heading the robot comes to rest at,
        braking now at its acceleration limit, is within half the tolerance: no crawl onto
        the heading first, and the resting pose keeps a margin for localisation error."""
        p = self.params
        w = velocity[1]
        resting_error = error - math.copysign(w * w / (2.0 * p.acc_lim_theta), w)
        if abs(error) <= p.yaw_goal_tolerance and abs(resting_error) <= 0.5 * p.yaw_goal_tolerance:
            return Command(0.0, 0.0, "arrived")
        return self._turn(error, velocity, "align")

    def _samples(self, velocity):
        p = self.params
        period = 1.0 / p.controller_frequency
        v0, w0 = velocity
        v_low = max(0.0, v0 - p.acc_lim_x * period)
        v_high = min(self._top_speed(), v0 + p.acc_lim_x * period)
        w_low = max(-p.max_vel_theta, w0 - p.acc_lim_theta * period)
        w_high = min(p.max_vel_theta, w0 + p.acc_lim_theta * period)
        vs = np.linspace(v_low, max(v_low, v_high), p.vx_samples)
        straight = [0.0] if w_low <= 0.0 <= w_high else []
        ws = np.unique(np.concatenate([np.linspace(w_low, w_high, p.vth_samples), straight]))
        v_grid, w_grid = np.meshgrid(vs, ws, indexing="ij")
        return v_grid.ravel(), w_grid.ravel()

    def _safe(self, trajectories, costs, costmap):
        """Arcs that keep the robot's circle (the footprint turning on the spot) off obstacles.
        Where there are none (a tight passage, a bump in localisation left the robot in the
        band where the circle touches), the arcs that keep escape_clearance from obstacles
        and end outside the band, or the robot could never leave."""
        valid = costs.max(axis=1) < INSCRIBED
        moving = np.hypot(*(trajectories[:, -1, :2] - trajectories[:, 0, :2]).T) > 0.02
        if (valid & moving).any():
            return valid
        clearance = costmap.clearance_at(trajectories[..., 0], trajectories[..., 1]).min(axis=1)
        return valid | ((clearance >= self.params.escape_clearance) & (costs[:, -1] < INSCRIBED))

    def rollout(self, pose, v, w):
        """Poses (S x T x 3) along arcs of constant (v, w) from `pose`."""
        p = self.params
        steps = max(1, int(round(p.sim_time / p.sim_granularity)))
        t = np.arange(1, steps + 1)[None, :] * p.sim_granularity
        v, w = np.asarray(v)[:, None], np.asarray(w)[:, None]
        x0, y0, yaw0 = pose
        yaw = yaw0 + w * t
        straight = np.abs(w) < 1e-6
        safe_w = np.where(straight, 1.0, w)
        xs = np.where(straight, x0 + v * t * math.cos(yaw0), x0 + v / safe_w * (np.sin(yaw) - math.sin(yaw0)))
        ys = np.where(straight, y0 + v * t * math.sin(yaw0), y0 - v / safe_w * (np.cos(yaw) - math.cos(yaw0)))
        return np.stack([xs, ys, np.broadcast_to(yaw, xs.shape)], axis=-1)

    def _best_arc(self, pose, velocity, carrot, near_goal, distance, costmap):
        p = self.params
        v, w = self._samples(velocity)
        if near_goal:
            # Slow down with the distance left, so the robot stops inside the tolerance.
            braking = math.sqrt(2.0 * p.approach_deceleration * max(0.0, distance - 0.3 * p.xy_goal_tolerance))
            v_cap = max(p.min_approach_vel, min(self._top_speed(), braking))
            keep = v <= v_cap + 1e-9
            if not keep.any():
                keep = v <= v.min() + 1e-9
            v, w = v[keep], w[keep]
        trajectories = self.rollout(pose, v, w)
        costs = costmap.cost_at(trajectories[..., 0], trajectories[..., 1]).astype(float)
        if near_goal:
            # Judge each arc where it passes closest to the goal, sooner being better: judged at
            # its end, an arc fast enough to pass the goal would lose to a crawl that ends on it.
            ends, elapsed, reached = _closest_approach(pose, trajectories, carrot, p.sim_granularity)
            time_cost = elapsed * p.approach_time_weight
            # The robot stops there: past the goal, beyond one sample of braking room, an arc
            # leads nowhere the robot goes, so what lies there (a wall behind the goal) is no cost.
            costs[np.arange(costs.shape[1])[None, :] > reached[:, None] + 1] = 0.0
            # Nor is the cost of the goal's own cell, which every arc that gets there pays.
            unavoidable = float(costmap.cost_at(np.array([carrot[0]]), np.array([carrot[1]]))[0])
        else:
            ends = trajectories[:, -1, :]
            time_cost = 0.0
            unavoidable = 0.0
        valid = self._safe(trajectories, costs, costmap)
        worst = np.maximum(costs.max(axis=1) - unavoidable, 0.0)
        if not valid.any():
            self.last_trajectory = None
            return Command(0.0, 0.0, "blocked")
        goal_cost = np.hypot(ends[:, 0] - carrot[0], ends[:, 1] - carrot[1]) + time_cost
        segment = self.plan[self._progress_index:self._progress_index + 80]
        path_cost = np.min(np.hypot(ends[:, 0:1] - segment[None, :, 0], ends[:, 1:2] - segment[None, :, 1]), axis=1)
        direction = np.arctan2(carrot[1] - ends[:, 1], carrot[0] - ends[:, 0])
        close = np.hypot(ends[:, 0] - carrot[0], ends[:, 1] - carrot[1]) < 0.1  # on the carrot, no direction
        heading_cost = np.where(close, 0.0, np.abs(wrap_angle(direction - ends[:, 2])))
        score = (p.goal_distance_bias * goal_cost + p.path_distance_bias * path_cost
                 + p.heading_bias * heading_cost + p.occdist_scale * worst / 252.0)
        score[~valid] = np.inf
        best = int(np.argmin(score))
        self.last_trajectory = trajectories[best]
        return Command(float(v[best]), float(w[best]), "approach" if near_goal else "follow")


def _closest_approach(pose, trajectories, point, step):
    """Where (S x 3 poses) and when (S seconds) each of the S rolled-out arcs passes closest
    to `point`, between its samples too (judged only at its samples, a fast arc, whose
    samples lie further apart, would seem to miss the point by more than a slow one), and
    the index of the first sample at or past that place (S)."""
    start = np.broadcast_to(np.asarray(pose, dtype=float), (len(trajectories), 1, 3))
    poses = np.concatenate([start, trajectories], axis=1)
    a, b = poses[:, :-1, :], poses[:, 1:, :]
    chord = b[..., :2] - a[..., :2]
    length_sq = np.maximum((chord ** 2).sum(axis=-1), 1e-12)
    along = np.clip(((point[:2] - a[..., :2]) * chord).sum(axis=-1) / length_sq, 0.0, 1.0)
    nearest = a + along[..., None] * (b - a)
    segment = np.argmin(np.hypot(nearest[..., 0] - point[0], nearest[..., 1] - point[1]), axis=1)
    rows = np.arange(len(trajectories))
    return nearest[rows, segment], (segment + along[rows, segment]) * step, segment
