"""The status node (from the install space) against a real roscore, with snapctl stood in for by a script:
navigation running on a simulated robot, which the snap tests do not cover (they run the fake robot)."""
import subprocess
import time

from testkit.ros_harness import PRIME_ROS

SNAPCTL = """#!/bin/sh
case "$1" in
  services) printf '%s\\n' 'Service Startup Current Notes' 'turtlebot3c.roscore enabled active -' \\
    'turtlebot3c.core enabled active -' 'turtlebot3c.teleop enabled active -' \\
    'turtlebot3c.mapping disabled inactive -' 'turtlebot3c.navigation enabled active -' ;;
  is-connected) exit 1 ;;
  get) echo '{"simulation": true, "lds-model": "LDS-01", "turtlebot3-model": "burger"}' ;;
esac
"""
SCAN = {"header": {"frame_id": "base_scan"}, "angle_increment": 0.0174533, "range_max": 3.5, "ranges": [1.0] * 360}
POSE = {"header": {"frame_id": "map"}, "pose": {"pose": {"position": {"x": 1.25, "y": -0.5}, "orientation": {"w": 1.0}},
                                                "covariance": [0.01] + [0.0] * 6 + [0.01] + [0.0] * 28}}


def run_status(ros_master, tmp_path, *args, master_uri=None):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    (bin_dir / "snapctl").write_text(SNAPCTL)
    (bin_dir / "snapctl").chmod(0o755)
    env = dict(ros_master.env, PATH=f"{bin_dir}:{ros_master.env['PATH']}", SNAP_COMMON=str(tmp_path / "common"),
               ROS_MASTER_URI=master_uri or ros_master.uri)
    started = time.monotonic()
    done = subprocess.run([str(PRIME_ROS / "lib" / "turtlebot3c_status" / "status")] + list(args), env=env,
                          capture_output=True, text=True, timeout=60)
    return done, time.monotonic() - started


def test_navigation_localised_with_a_goal_reached_on_a_simulated_robot(ros_master, tmp_path):
    probe = ros_master.probe
    probe.publish("/mux/selected", "std_msgs/String", {"data": "nav_vel"}, latch=True)
    probe.publish("/scan", "sensor_msgs/LaserScan", SCAN, latch=True)
    probe.publish("/odom", "nav_msgs/Odometry", {"header": {"frame_id": "odom"}}, latch=True)
    probe.publish("/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped", POSE, latch=True)
    probe.publish("/move_base/status", "actionlib_msgs/GoalStatusArray",
                  {"status_list": [{"status": 3, "text": "Goal reached."}]}, latch=True)
    done, took = run_status(ros_master, tmp_path)
    print(f"\n--- status: simulation, navigation running (exit {done.returncode}, {took:.1f} s)\n{done.stdout}")
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert lines[2] == "\u2714 raw-usb     not needed (simulation=true)"
    assert lines[4] == "\u2714 OpenCR      simulated (simulation=true)"
    assert lines[-1] == "\u2714 navigation  localised at (1.25, -0.50); goal reached"
    assert "navigation active" in lines[0]


def test_a_master_that_is_gone_is_said_quickly_outside_the_snap_too(ros_master, tmp_path):
    done, took = run_status(ros_master, tmp_path, "--json", master_uri="http://127.0.0.1:9")  # nothing listens
    print(f"\nno master: answered in {took:.1f} s")
    assert done.returncode == 1 and took < 5.0
    assert '"ok": false' in done.stdout and "Traceback" not in done.stderr
