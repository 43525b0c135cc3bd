"""The README's demo (demo/run), shortened: the snap installed through snapsim maps the
world while the explorer drives, saves and installs the map, and navigation reaches a goal
on it; in simulation and on the real-robot path against the fake OpenCR and LIDAR.
Also the demo's pieces that need no ROS: the tours, the map score, the pictures."""
import json
import math
import os
import re
import subprocess

import numpy as np
import pytest
from PIL import Image

from demo import explorer
from demo.pictures import MapPicture
from testkit import ros_harness
from turtlebot3c_common.se2 import compose
from turtlebot3c_description.models import get_model
from turtlebot3c_sim import evaluation
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world

DEMO = ros_harness.REPO / "demo" / "run"
DATED_MAP = re.compile(r"^\d{4}-\d{2}-\d{2}_\d{2}-\d{2}-\d{2}(_\d+)?\.yaml$")


def run_demo(folder, *args):
    env = dict(os.environ, TURTLEBOT3C_BUILD_DIR=str(ros_harness.BUILD))
    env[ros_harness.RUN_MARKER] = ros_harness.RUN_ID
    env["SNAPSIM_PASSENV"] = ros_harness.RUN_MARKER
    summary_file = folder / "summary.json"
    done = subprocess.run([str(DEMO), "--no-setup", "--quick", "--out", str(folder / "out"),
                           "--summary-json", str(summary_file), *args],
                          env=env, capture_output=True, text=True, timeout=400)
    report = f"exit {done.returncode}\n--- stdout\n{done.stdout[-6000:]}\n--- stderr\n{done.stderr[-4000:]}"
    assert summary_file.exists(), report
    return done, json.loads(summary_file.read_text()), report


def assert_demo_mapped_and_navigated(folder, done, summary, report):
    assert done.returncode == 0 and summary["ok"], report
    # mapping's stop refined the session before it saved the map (snap logs kept by the demo)
    assert "save_map: map refined: " in (folder / "out" / "logs" / "snap.log").read_text(), report
    assert "demo summary" in done.stdout and "goals reached: 1/1" in done.stdout, report
    assert DATED_MAP.match(os.path.basename(summary["map_file"])), summary["map_file"]
    assert {os.path.basename(summary["map_file"]), "current_map.yaml"} <= set(summary["maps_in_folder"])
    assert summary["map_agreement"] >= 0.9, report
    assert summary["map_coverage"] >= 0.3, report
    goal = summary["goals"][0]
    assert goal["status"] == "SUCCEEDED" and goal["true_error_m"] <= 0.25, report
    for key in ("mapping_png", "navigation_png"):
        with Image.open(summary[key]) as picture:
            assert picture.format == "PNG" and picture.width >= 100 and picture.height >= 100


# About 2-3 minutes each on a loaded 2-core machine; the deadlines leave room for worse.
@pytest.mark.timeout(420)
def test_quick_demo_in_simulation_maps_the_world_and_reaches_the_goal_on_the_saved_map(tmp_path):
    done, summary, report = run_demo(tmp_path)
    assert_demo_mapped_and_navigated(tmp_path, done, summary, report)
    assert summary["mode"] == "simulation"


@pytest.mark.timeout(420)
def test_quick_demo_on_the_fake_robot_maps_and_navigates_through_the_real_drivers(tmp_path):
    done, summary, report = run_demo(tmp_path, "--real-robot")
    assert_demo_mapped_and_navigated(tmp_path, done, summary, report)
    assert "opencr-port=/dev/pts/" in done.stdout, report


# --- the pieces, without ROS ------------------------------------------------------------

@pytest.mark.parametrize("world_name", sorted(explorer.TOURS))
@pytest.mark.parametrize("length", ["quick", "full"])
def test_tour_driven_in_the_stepping_simulator_visits_every_waypoint_without_contact(world_name, length):
    world = load_world(world_name)
    model = get_model("waffle_pi")
    sim = Simulation(world, model="waffle_pi", pose=world.spawn_pose, noise=NoiseConfig.none())
    steps, _ = explorer.tour_for(world_name, length)
    legs = explorer.plan_tour(world, sim.pose[:2], steps, model.robot_radius)
    for leg in legs:
        controller = explorer.Spin(0.4) if leg is explorer.SPIN else explorer.PurePursuit(leg, 0.18, 0.8)
        for _ in range(3000):  # 300 s of simulated time at most per leg
            command = controller.command(sim.pose)
            if command is None:
                break
            sim.set_command(*command)
            sim.step(0.1)
        else:
            pytest.fail(f"leg to {leg if leg is explorer.SPIN else leg[-1]} never finished; robot at {sim.pose}")
        if leg is not explorer.SPIN:
            assert math.hypot(sim.pose[0] - leg[-1][0], sim.pose[1] - leg[-1][1]) < 0.1
    assert sim.collisions == 0


@pytest.mark.parametrize("world_name", sorted(explorer.TOURS))
def test_goals_of_every_tour_lie_in_free_space_clear_of_the_robot(world_name):
    world = load_world(world_name)
    radius = get_model("waffle_pi").robot_radius
    for length in ("quick", "full"):
        _, goals = explorer.tour_for(world_name, length)
        for x, y, _ in goals:
            assert not world.contains([(x, y)])[0] and world.clearance(x, y) > radius + 0.1, (x, y)


def test_unknown_world_has_no_tour_and_says_which_worlds_have_one():
    with pytest.raises(ValueError, match="turtlebot3_world"):
        explorer.tour_for("moon", "quick")


def perfect_map(world, resolution=0.05):
    xmin, ymin, xmax, ymax = world.bounds
    width, height = int(math.ceil((xmax - xmin) / resolution)), int(math.ceil((ymax - ymin) / resolution))
    return np.where(world.rasterize(resolution, (xmin, ymin), width, height), 100, 0), (xmin, ymin, 0.0)


def test_a_perfect_map_agrees_with_the_world_and_covers_it():
    world = load_world("turtlebot3_world")
    data, origin = perfect_map(world)
    score = evaluation.score_map(data, 0.05, origin, world, (0.0, 0.0, 0.0), world.spawn_pose[:2])
    assert score.agreement == 1.0 and score.coverage == 1.0
    assert score.known_cells == data.size


def test_map_score_follows_the_map_frame_and_sees_a_shifted_map():
    world = load_world("turtlebot3_world")
    data, origin = perfect_map(world)
    # The same map, its frame 1 m along x and turned a quarter: described through that frame, it still agrees.
    frame = (1.0, 0.0, math.pi / 2)
    rotated = np.rot90(data)  # in the new frame x = y_world, y = 1 - x_world
    rotated_origin = (origin[1], 1.0 - (origin[0] + data.shape[1] * 0.05), 0.0)
    assert evaluation.score_map(rotated, 0.05, rotated_origin, world, frame, world.spawn_pose[:2]).agreement \
        > 0.99
    assert evaluation.score_map(data, 0.05, (origin[0] + 0.3, origin[1], 0.0), world, (0.0, 0.0, 0.0),
                                world.spawn_pose[:2]).agreement < 0.95


def test_unknown_cells_count_neither_for_agreement_nor_coverage():
    world = load_world("turtlebot3_world")
    data, origin = perfect_map(world)
    data[:, : data.shape[1] // 2] = -1
    score = evaluation.score_map(data, 0.05, origin, world, (0.0, 0.0, 0.0), world.spawn_pose[:2])
    assert score.agreement == 1.0 and 0.3 < score.coverage < 0.7


def test_frame_in_world_recovers_a_frame_from_one_pose_known_in_both():
    frame = (0.4, -1.2, 0.7)
    pose_in_frame = (1.0, 2.0, -0.3)
    pose_in_world = compose(frame, pose_in_frame)
    assert evaluation.frame_in_world(pose_in_world, pose_in_frame) == pytest.approx(frame)


def test_map_picture_puts_the_lowest_row_at_the_bottom_and_paths_where_they_are(tmp_path):
    data = np.full((20, 30), -1)
    data[0, :] = 100  # the lowest y: a wall at the bottom of the picture
    data[10, 5:25] = 0
    picture = MapPicture(data, 0.1, (-1.0, -1.0, 0.0), scale=2)
    picture.path([(-0.5, 0.05), (1.0, 0.05)], (255, 0, 0), width=1)
    path = picture.save(tmp_path / "map.png")
    with Image.open(path) as image:
        assert image.size == (60, 40)
        assert image.getpixel((10, 39)) == (0, 0, 0)
        assert image.getpixel((10, 0)) == (205, 205, 205)
        assert image.getpixel((15, 19)) == (255, 0, 0)
