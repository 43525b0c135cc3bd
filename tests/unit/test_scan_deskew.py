"""Deskewing: a scan measured beam by beam while the robot moves, brought back onto the world it saw."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from turtlebot3c_common.scan_deskew import (
    beam_motion,
    beam_times,
    deskew_points,
    deskew_ranges,
    reference_time,
    sample_times,
    time_increment,
)
from turtlebot3c_common.se2 import transform_points
from turtlebot3c_navigation.costmap import Costmap
from turtlebot3c_navigation.grid_info import GridInfo
from turtlebot3c_slam.slam_scan import ScanGeometry, scan_rays

BEAMS = 360
ANGLES = np.arange(BEAMS) * 2.0 * math.pi / BEAMS
LDS_INCREMENT = -0.2 / BEAMS  # the LDS: a revolution in 0.2 s, beam 0 measured last
WALL_X = 2.0  # a wall along x = 2 m in the world
MOUNT = (-0.064, 0.0, 0.0)  # the burger's LIDAR, behind the wheels' axle


class TurningRobot:
    """A robot turning at `rate` rad/s while driving at `speed` m/s (an arc), exact at any time."""

    def __init__(self, rate, speed=0.0, start=(0.0, 0.0, 0.0), start_time=10.0):
        self.rate, self.speed, self.start, self.start_time = rate, speed, start, start_time

    def pose_at(self, t):
        x0, y0, yaw0 = self.start
        dt = t - self.start_time
        yaw = yaw0 + self.rate * dt
        if abs(self.rate) < 1e-12:
            return (x0 + self.speed * dt * math.cos(yaw0), y0 + self.speed * dt * math.sin(yaw0), yaw)
        radius = self.speed / self.rate
        return (x0 + radius * (math.sin(yaw) - math.sin(yaw0)), y0 - radius * (math.cos(yaw) - math.cos(yaw0)), yaw)


def scan_of_wall(robot, stamp, time_increment, mount=(0.0, 0.0, 0.0)):
    """Ranges a LIDAR on `robot` measures of the wall x = WALL_X, beam i at stamp + i * time_increment
    (0 = no return, as the LDS report it)."""
    ranges = np.zeros(BEAMS)
    for beam, t in enumerate(beam_times(stamp, BEAMS, time_increment)):
        pose = robot.pose_at(t)
        sx, sy = transform_points(pose, [mount[:2]])[0]
        direction = pose[2] + mount[2] + ANGLES[beam]
        if math.cos(direction) > 0.05:
            ranges[beam] = (WALL_X - sx) / math.cos(direction)
    return ranges


def world_points(robot, reference, points_in_robot):
    return transform_points(robot.pose_at(reference), points_in_robot)


def test_an_instantaneous_scan_is_left_as_it_is():
    assert beam_motion(5.0, BEAMS, 0.0, lambda t: pytest.fail("no odometry is needed")) is None
    ranges = np.linspace(0.5, 3.0, BEAMS)
    new_ranges, new_angles = deskew_ranges(ranges, ANGLES, MOUNT, None)
    assert np.array_equal(new_ranges, ranges) and np.array_equal(new_angles, ANGLES)
    geometry = ScanGeometry(0.0, 2 * math.pi / BEAMS, BEAMS, 0.12, 3.5, MOUNT)
    assert np.array_equal(scan_rays(geometry, ranges, 8.0, None).hits, scan_rays(geometry, ranges, 8.0).hits)


@pytest.mark.parametrize("increment", [float("nan"), float("inf"), -float("inf")])
def test_a_time_between_beams_that_is_no_number_counts_as_an_instantaneous_scan(increment):
    # Another driver's scan, or a damaged recording: the nodes and the replays take the scan as it is
    # (beam_motion would raise "cannot convert float NaN to integer" at each such scan).
    scan = SimpleNamespace(time_increment=increment)
    assert time_increment(scan) == 0.0
    assert beam_motion(5.0, BEAMS, time_increment(scan), lambda t: pytest.fail("no odometry is needed")) is None
    assert time_increment(SimpleNamespace(time_increment=LDS_INCREMENT)) == LDS_INCREMENT


def test_reference_is_the_latest_beam_whichever_way_the_beams_run():
    assert reference_time(10.0, BEAMS, LDS_INCREMENT) == 10.0
    assert reference_time(10.0, BEAMS, 0.2 / BEAMS) == pytest.approx(10.0 + 0.2 * 359 / 360)
    times = sample_times(10.0, BEAMS, LDS_INCREMENT, step=0.02)
    assert times[0] == pytest.approx(10.0 - 0.2 * 359 / 360) and times[-1] == 10.0
    assert np.all(np.diff(times) <= 0.02 + 1e-12)


@pytest.mark.parametrize("rate, speed", [(0.8, 0.0), (-0.6, 0.0), (1.5, 0.2)])
def test_deskewed_end_points_of_a_turning_robot_lie_on_the_wall(rate, speed):
    robot = TurningRobot(rate, speed)
    stamp = 10.5
    ranges = scan_of_wall(robot, stamp, LDS_INCREMENT)
    returned = ranges > 0
    reference = reference_time(stamp, BEAMS, LDS_INCREMENT)
    motion = beam_motion(stamp, BEAMS, LDS_INCREMENT, robot.pose_at)
    assert motion.shape == (BEAMS, 3)

    raw_ends = np.column_stack((ranges * np.cos(ANGLES), ranges * np.sin(ANGLES)))[returned]
    deskewed = deskew_points(raw_ends, motion[returned])
    # tf-like interpolation between poses 20 ms apart: exact for a spin, within a millimetre on an arc
    assert np.abs(world_points(robot, reference, deskewed)[:, 0] - WALL_X).max() < 1e-3
    # one pose for the whole scan, as before: the wall comes out bent by centimetres
    assert np.abs(world_points(robot, reference, raw_ends)[:, 0] - WALL_X).max() > 0.05


def test_deskewed_ranges_from_a_mounted_lidar_lie_on_the_wall_and_no_return_stays_no_return():
    robot = TurningRobot(0.8, 0.1)
    stamp = 10.5
    ranges = scan_of_wall(robot, stamp, LDS_INCREMENT, MOUNT)
    ranges[5] = np.inf
    ranges[6] = np.nan
    motion = beam_motion(stamp, BEAMS, LDS_INCREMENT, robot.pose_at)
    new_ranges, new_angles = deskew_ranges(ranges, ANGLES, MOUNT, motion)
    assert new_ranges[5] == np.inf and np.isnan(new_ranges[6])
    assert np.array_equal(new_ranges == 0, ranges == 0)  # the LDS's "no return" (0) is kept
    returned = new_ranges > 0
    returned[[5, 6]] = False
    ends = np.column_stack((MOUNT[0] + new_ranges * np.cos(new_angles), new_ranges * np.sin(new_angles)))[returned]
    assert np.abs(world_points(robot, stamp, ends)[:, 0] - WALL_X).max() < 1e-3


def test_slam_rays_of_a_turning_robot_are_deskewed_onto_the_wall():
    robot = TurningRobot(-0.8)
    stamp = 10.5
    ranges = scan_of_wall(robot, stamp, LDS_INCREMENT, MOUNT)
    geometry = ScanGeometry(0.0, 2 * math.pi / BEAMS, BEAMS, 0.12, 8.0, MOUNT)
    motion = beam_motion(stamp, BEAMS, LDS_INCREMENT, robot.pose_at)
    hits = scan_rays(geometry, ranges, 8.0, motion).hits
    assert len(hits) > 100
    assert np.abs(world_points(robot, stamp, hits)[:, 0] - WALL_X).max() < 1e-3
    skewed = scan_rays(geometry, ranges, 8.0).hits
    assert np.abs(world_points(robot, stamp, skewed)[:, 0] - WALL_X).max() > 0.05


def test_costmap_marks_only_the_wall_from_a_deskewed_scan_of_a_turning_robot():
    robot = TurningRobot(0.8)
    stamp = 10.5
    ranges = scan_of_wall(robot, stamp, LDS_INCREMENT)
    ranges[ranges > 3.0] = 0.0  # marking stops at obstacle_range anyway
    info = GridInfo(0.05, 100, 100, -2.5, -2.5)

    def marked_columns(scan_ranges, scan_angles):
        costmap = Costmap(info)
        costmap.update_from_scan(robot.pose_at(stamp), scan_ranges, scan_angles)
        _, columns = np.nonzero(costmap.obstacles)
        return set(columns.tolist())

    wall_column = int(math.floor((WALL_X - info.origin_x) / info.resolution))
    motion = beam_motion(stamp, BEAMS, LDS_INCREMENT, robot.pose_at)
    assert marked_columns(*deskew_ranges(ranges, ANGLES, (0.0, 0.0, 0.0), motion)) <= {wall_column - 1, wall_column}
    assert len(marked_columns(ranges, ANGLES) - {wall_column - 1, wall_column}) > 0
