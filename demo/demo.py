"""The demo's steps: the guide's final test, with progress lines, a summary and pictures.

  install the snap -> set simulation (and the model, the master) -> start the simulator
  (or the fake OpenCR and LIDAR) -> start mapping -> drive around -> stop mapping (map
  saved and made current) -> start --enable navigation -> goals -> stop everything.
"""
import json
import math
import os
import shutil
import tempfile
import time
import xmlrpc.client
from pathlib import Path

from testkit import processes, ros_harness
from testkit.waiting import wait_until
from turtlebot3c_common import se2
from turtlebot3c_sim import evaluation

from . import explorer, snap_control
from .snap_control import SnapCommandError

GOAL_TOLERANCE = 0.25  # m between the goal and where the robot truly stopped (localisation error included)


class Progress:
    def __init__(self):
        self.started = time.monotonic()
        self.step_started = self.started
        self.times = {}

    def say(self, text):
        print(f"[{time.monotonic() - self.started:6.1f} s] {text}", flush=True)

    def step(self, name, text):
        self.step_started = time.monotonic()
        self.current = name
        self.say(text)

    def done(self, text=""):
        took = time.monotonic() - self.step_started
        self.times[self.current] = round(took, 1)
        self.say(f"  ... {text + ', ' if text else ''}{took:.1f} s")


class Demo:
    def __init__(self, options):
        self.options = options
        self.out = Path(options.out).resolve()
        self.logs = self.out / "logs"
        self.progress = Progress()
        self.background = []
        self.snap = None
        self.link = None
        self.summary = {"mode": "real-robot (fake OpenCR + LIDAR)" if options.real_robot else "simulation",
                        "snap_cli": options.snap_cli, "model": options.model, "world": options.world,
                        "tour": "quick" if options.quick else "full", "ok": False}

    # --- set-up -------------------------------------------------------------------------

    def environment(self):
        env = dict(os.environ)
        env.update(ROS_MASTER_URI=self.master_uri, ROS_HOSTNAME="localhost", ROS_LOG_DIR=str(self.logs / "ros"))
        env.pop("ROS_IP", None)
        return env

    def start_master(self):
        port = ros_harness.free_port() if self.options.snap_cli == "snapsim" else 11311
        self.master_uri = f"http://localhost:{port}"
        os.environ.update(ROS_MASTER_URI=self.master_uri, ROS_HOSTNAME="localhost")
        os.environ.pop("ROS_IP", None)
        self.env = self.environment()
        self.progress.step("master", f"roscore on {self.master_uri} (the snap's daemons use it too)")
        self.background.append(processes.roscore(port, self.logs / "roscore.log", self.env))
        processes.wait_for_master(self.master_uri, timeout=60)
        self.progress.done()

    def make_snap(self):
        if self.options.snap_cli == "snapsim":
            root = Path(tempfile.mkdtemp(prefix="turtlebot3c-demo-root-"))
            self.snap = snap_control.Snapsim(root, self.master_uri, self.env)
            self.progress.say(f"snapsim root: {root}")
        else:
            self.snap = snap_control.RealSnap(self.options.snap_file, self.env)

    def install(self):
        self.progress.step("install", "snap install --dangerous (turtlebot3c)")
        self.progress.say("  " + self.snap.install(snap_control.REPO))
        self.progress.done()

    def start_robot(self):
        options = self.options
        values = {"turtlebot3-model": options.model, "ros-master-host": "localhost"}
        if options.real_robot:
            self.progress.step("robot", "fake robot: OpenCR board and LIDAR on pseudo-terminals")
            fake, opencr_link, lds_link = processes.fake_robot(self.out / "devices", options.world, options.model,
                                                               options.lds_model, self.logs / "fake_robot.log",
                                                               self.env)
            self.background.append(fake)
            wait_until(lambda: opencr_link.exists() and lds_link.exists(), 60, "the fake robot's serial links")
            values.update({"simulation": "false", "lds-model": options.lds_model,
                           "opencr-port": os.path.realpath(opencr_link), "lds-port": os.path.realpath(lds_link)})
            self.progress.done(f"opencr-port={values['opencr-port']} lds-port={values['lds-port']}")
            self.configure(values)
        else:
            values["simulation"] = "true"
            self.configure(values)
            self.progress.step("simulator", f"roslaunch turtlebot3c_sim turtlebot3_world.launch world:={options.world}")
            self.background.append(processes.simulator(options.world, options.model, self.logs / "simulator.log",
                                                       self.env))
            self.progress.done()
        self.progress.step("bringup", "waiting for the robot: core, teleop's mux, ground truth")
        from .ros_link import RosLink
        self.link = RosLink()
        expected = ["/robot_state_publisher", "/mux", "/velocity_watchdog"]
        if options.real_robot:
            expected += ["/turtlebot3_core", "/turtlebot3_lds"]
        wait_until(lambda: all(self.node_running(name) for name in expected), 180,
                   lambda: f"nodes {expected}\n{self.snap.logs('40')}")
        wait_until(self.link.true_pose, 60, "the simulator's ground truth")
        wait_until(lambda: self.link.odometry_tf() is not None, 60, "tf odom -> base_footprint")
        self.progress.done()

    def configure(self, values):
        self.progress.step("configure", "snap set turtlebot3c " + " ".join(f"{k}={v}" for k, v in values.items()))
        self.snap.set(**{key.replace("-", "_"): value for key, value in values.items()})
        if self.snap.kind == "snap":
            # The daemons started at install with the default master (<hostname>.local),
            # which may not resolve here; restart them whatever state they reached.
            self.snap.restart("core", "teleop")
        self.progress.done()

    def node_running(self, name):
        try:
            code, _, _ = xmlrpc.client.ServerProxy(self.master_uri).lookupNode("/turtlebot3c_demo", name)
        except OSError:
            return False
        return code == 1

    # --- mapping ------------------------------------------------------------------------

    def map_world(self):
        options = self.options
        from turtlebot3c_description.models import get_model
        from turtlebot3c_sim.world import load_world
        self.world = load_world(options.world)
        model = get_model(options.model)
        steps, self.goals = explorer.tour_for(options.world, "quick" if options.quick else "full")

        self.progress.step("mapping-start", "snap start turtlebot3c.mapping")
        self.snap.start("mapping")
        wait_until(self.link.map_pose, 180, lambda: f"SLAM's map -> base_footprint\n{self.snap.logs('40')}")
        wait_until(lambda: self.link.has_key_vel_listener(), 30, "the mux listening on key_vel")
        self.map_in_world = self.locate_map_frame()
        self.progress.done("map frame at ({:.2f}, {:.2f}, {:.2f}) in the world".format(*self.map_in_world))

        self.progress.step("drive", f"driving the {self.summary['tour']} tour of {options.world} on key_vel")
        start = self.link.true_pose()
        legs = explorer.plan_tour(self.world, start[:2], steps, model.robot_radius)
        max_linear = min(options.speed, model.max_linear_velocity)
        turn_rate = options.turn_rate or 0.8
        max_angular = min(turn_rate, model.max_angular_velocity)
        self.slam_path = []
        self.link.start_recording()
        for index, leg in enumerate(legs, 1):
            if leg is explorer.SPIN:
                # At half the turn rate: a whole revolution of scans seen slowly, as a person would.
                controller, what, timeout = explorer.Spin(max_angular / 2), "a turn on the spot", 90
            else:
                controller = explorer.PurePursuit(leg, max_linear, max_angular)
                what = "to ({:.2f}, {:.2f}), {:.1f} m".format(*leg[-1], evaluation.path_length(leg))
                timeout = 30 + 3 * evaluation.path_length(leg) / max_linear
            leg_started = time.monotonic()
            finished = self.link.follow(controller, timeout, on_step=self.record_slam_pose)
            stale = self.link.stale_ticks
            stale = f" (held still {stale} times: no fresh ground truth)" if stale else ""
            self.progress.say(f"  leg {index}/{len(legs)}: {what}: "
                              f"{'done' if finished else 'GAVE UP'} in {time.monotonic() - leg_started:.0f} s{stale}")
        # SLAM publishes its map at a bounded rate (every 2 s), and only when it changed: give
        # the last scans time to reach it, unless it was already up to date.
        driven_until = time.monotonic()
        try:
            wait_until(lambda: self.link.map_updated_since(driven_until), 5, "a newer map")
        except TimeoutError:
            pass
        self.truth_path = self.link.stop_recording()
        self.final_slam_pose = wait_until(self.link.map_pose, 10, "SLAM's last pose")
        driven = evaluation.path_length([(x, y) for _, x, y, _ in self.truth_path])
        self.summary["driven_m"] = round(driven, 2)
        self.progress.done(f"{driven:.1f} m driven")

        self.progress.step("mapping-stop", "snap stop turtlebot3c.mapping (saves the map, makes it current)")
        self.snap.stop("mapping")
        current = self.snap.current_map()
        if current is None:
            raise RuntimeError(f"no current_map.yaml in {' or '.join(map(str, self.snap.map_dirs))} after "
                               f"stopping mapping\n{self.snap.logs('40')}")
        self.map_file = current.resolve()
        # The snap's map folder may go with the snapsim root: keep a copy beside the pictures.
        shutil.copytree(current.parent, self.out / "maps", symlinks=True)
        self.load_saved_map()
        self.progress.done(f"current_map.yaml -> {self.map_file.name}")

    def locate_map_frame(self):
        """The map frame's pose in the world, from SLAM's pose and the truth at rest."""
        pairs = []
        for _ in range(5):
            truth, estimate = self.link.true_pose(), self.link.map_pose()
            if truth and estimate:
                pairs.append(evaluation.frame_in_world(truth, estimate))
            time.sleep(0.1)
        return pairs[-1]

    def record_slam_pose(self, _truth):
        estimate = self.link.map_pose(timeout=0.0)
        if estimate:
            self.slam_path.append(estimate[:2])

    def load_saved_map(self):
        from turtlebot3c_maps.map_files import load_map
        saved = load_map(self.map_file)
        self.map = saved
        score = evaluation.score_map(saved.data, saved.resolution, saved.origin, self.world, self.map_in_world,
                                     self.truth_path[0][1:3] if self.truth_path else self.world.spawn_pose[:2])
        self.summary.update({
            "map_file": str(self.map_file),
            "map_cells": [saved.width, saved.height],
            "map_size_m": [round(saved.width * saved.resolution, 2), round(saved.height * saved.resolution, 2)],
            "map_resolution": round(saved.resolution, 4),
            "map_known_cells": score.known_cells,
            "map_agreement": round(score.agreement, 4),
            "map_coverage": round(score.coverage, 4),
            "maps_in_folder": sorted(path.name for path in self.map_file.parent.glob("*.yaml")),
        })

    # --- navigation -----------------------------------------------------------------------

    def navigate(self):
        self.progress.step("navigation-start", "snap start --enable turtlebot3c.navigation")
        self.snap.start("navigation", enable=True)
        client = self.link.move_base_client(timeout=180)
        wait_until(self.link.initial_pose_listened, 60, "amcl listening on /initialpose")
        # As a person would in RViz ("2D Pose Estimate"): where the robot stood when mapping ended.
        since = time.monotonic()
        self.link.set_initial_pose(self.final_slam_pose)
        wait_until(lambda: self.link.amcl_settled(since, self.final_slam_pose, 0.2), 60,
                   "AMCL's pose to settle at the initial pose")
        self.progress.done("localised at ({:.2f}, {:.2f})".format(*self.final_slam_pose[:2]))

        world_to_map = se2.inverse(self.map_in_world)
        self.goal_results = []
        for index, goal_in_world in enumerate(self.goals, 1):
            goal = se2.compose(world_to_map, goal_in_world)
            self.progress.step(f"goal-{index}", f"goal {index}/{len(self.goals)}: ({goal[0]:.2f}, {goal[1]:.2f}, "
                               f"{math.degrees(goal[2]):.0f} deg) in map")
            sent = time.monotonic()
            self.link.start_recording()
            status, text, seconds = self.link.send_goal(client, goal, timeout=240)
            truth = self.link.stop_recording()
            final = self.link.true_pose()
            error = math.hypot(final[0] - goal_in_world[0], final[1] - goal_in_world[1]) if final else float("nan")
            plans = self.link.plans_since(sent)
            start = truth[0][1:3] if truth else None
            # The first plan made from where the robot stood (AMCL may still be settling for the very first).
            from_start = [plan for plan in plans if start is None or self.starts_near(plan, world_to_map, start)]
            plan = (from_start or plans or [[]])[0]
            reached = status == "SUCCEEDED" and error <= GOAL_TOLERANCE
            self.goal_results.append({
                "goal_map": [round(v, 3) for v in goal], "status": status, "text": text, "seconds": round(seconds, 1),
                "true_error_m": round(error, 3), "reached": reached,
                "plan_m": round(evaluation.path_length(plan), 2) if plan else None,
                "plans_published": len(plans),
                "driven_m": round(evaluation.path_length([(x, y) for _, x, y, _ in truth]), 2),
                "plan": plan,
                "driven": se2.transform_points(world_to_map, [(x, y) for _, x, y, _ in truth]).tolist()
                if truth else [],
            })
            self.progress.done(f"{status}{': ' + text if text else ''}, {error:.2f} m from the goal (truth)")
        self.summary["goals"] = [{key: value for key, value in result.items() if key not in ("plan", "driven")}
                                 for result in self.goal_results]
        self.summary["goals_reached"] = sum(result["reached"] for result in self.goal_results)

    @staticmethod
    def starts_near(plan, world_to_map, start_in_world, distance=0.3):
        start = se2.transform_points(world_to_map, [start_in_world])[0]
        return math.hypot(plan[0][0] - start[0], plan[0][1] - start[1]) <= distance

    # --- the end --------------------------------------------------------------------------

    def stop_everything(self):
        self.progress.step("stop", "snap stop turtlebot3c.navigation, then everything else")
        if self.snap is not None:
            try:
                if "navigation" in self.snap.active_services():
                    self.snap.stop("navigation", disable=True)
            except (SnapCommandError, OSError) as error:
                self.progress.say(f"  stopping navigation: {error}")
            self.save_logs()
            self.snap.finish()
        if self.link is not None:
            self.link.shutdown()
        for process in reversed(self.background):
            process.stop()
        self.progress.done()

    def save_logs(self):
        try:
            (self.logs / "snap.log").write_text(self.snap.logs("all"))
        except (SnapCommandError, OSError):
            pass

    def pictures(self):
        from .pictures import PATH_COLOURS, MapPicture
        saved = self.map
        world_to_map = se2.inverse(self.map_in_world)
        mapping = MapPicture(saved.data, saved.resolution, saved.origin)
        truth = se2.transform_points(world_to_map, [(x, y) for _, x, y, _ in self.truth_path])
        mapping.path(truth, (44, 160, 44), width=5)
        mapping.path(self.slam_path, (31, 119, 180), width=2)
        if len(truth):
            mapping.marker(truth[0][0], truth[0][1], (214, 39, 40), label="start")
        mapping.legend([((44, 160, 44), "driven path (ground truth)"), ((31, 119, 180), "SLAM's estimate")])
        paths = {"mapping_png": str(mapping.save(self.out / "map_with_driven_path.png"))}

        if getattr(self, "goal_results", None):
            navigation = MapPicture(saved.data, saved.resolution, saved.origin)
            legend = []
            for index, result in enumerate(self.goal_results):
                colour = PATH_COLOURS[index % len(PATH_COLOURS)]
                light = tuple(255 - (255 - c) // 3 for c in colour)
                navigation.path(result["driven"], light, width=7)
                navigation.path(result["plan"], colour, width=2)
                navigation.marker(result["goal_map"][0], result["goal_map"][1], colour, label=str(index + 1))
                legend.append((colour, f"goal {index + 1}: {result['status'].lower()} in {result['seconds']} s"))
            navigation.marker(self.final_slam_pose[0], self.final_slam_pose[1], (0, 0, 0), label="start")
            navigation.legend(legend + [((160, 160, 160), "global plan (line), driven path (band)")])
            paths["navigation_png"] = str(navigation.save(self.out / "navigation_paths.png"))
        self.summary.update(paths)

    def print_summary(self):
        s = self.summary
        lines = ["", "turtlebot3c demo summary",
                 f"  mode: {s['mode']}, {s['model']} in {s['world']}, {s['tour']} tour, through {s['snap_cli']}"]
        if "map_cells" in s:
            lines.append("  map: {} x {} cells at {} m = {} x {} m; {} cells known; agreement with the world "
                         "{:.1%}, free area covered {:.1%}".format(*s["map_cells"], s["map_resolution"],
                                                                   *s["map_size_m"], s["map_known_cells"],
                                                                   s["map_agreement"], s["map_coverage"]))
            lines.append(f"  map file: {s['map_file']}  (maps kept: {', '.join(s['maps_in_folder'])}; "
                         f"copied to {self.out / 'maps'})")
        if "driven_m" in s:
            lines.append(f"  driven while mapping: {s['driven_m']} m")
        for index, goal in enumerate(s.get("goals", []), 1):
            lines.append(f"  goal {index}: {goal['status']} in {goal['seconds']} s, {goal['true_error_m']} m from "
                         f"the goal, plan {goal['plan_m']} m, driven {goal['driven_m']} m")
        if "goals" in s:
            lines.append(f"  goals reached: {s['goals_reached']}/{len(s['goals'])}")
        lines.append("  times (s): " + ", ".join(f"{name} {seconds}" for name, seconds in s["times"].items()))
        for key in ("mapping_png", "navigation_png"):
            if key in s:
                lines.append(f"  picture: {s[key]}")
        if s.get("error"):
            lines.append(f"  FAILED: {s['error']}")
        lines.append(f"  logs: {self.logs}")
        print("\n".join(lines), flush=True)

    def run(self):
        if self.out.exists():
            shutil.rmtree(self.out)
        self.logs.mkdir(parents=True)
        try:
            self.start_master()
            self.make_snap()
            self.install()
            self.start_robot()
            self.map_world()
            self.navigate()
            self.summary["ok"] = self.summary["goals_reached"] == len(self.goals)
        except (RuntimeError, TimeoutError, SnapCommandError, OSError) as error:
            self.summary["error"] = f"{getattr(self.progress, 'current', 'start')}: {error}"
            self.progress.say(f"FAILED at {self.summary['error']}")
        finally:
            self.stop_everything()
        self.summary["times"] = dict(self.progress.times, total=round(time.monotonic() - self.progress.started, 1))
        if hasattr(self, "map"):
            self.pictures()
        self.print_summary()
        text = json.dumps(self.summary, indent=2) + "\n"
        (self.out / "summary.json").write_text(text)
        if self.options.summary_json:
            Path(self.options.summary_json).write_text(text)
        return 0 if self.summary["ok"] else 1

