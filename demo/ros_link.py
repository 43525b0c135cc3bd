"""The demo's own ROS node: what a person at RViz and a keyboard sees and does.

It reads the simulator's ground truth and tf (SLAM's or AMCL's estimate of the robot
in `map`), drives on `key_vel`, gives AMCL its initial pose, sends move_base goals by
action and records the global plans. rospy binds a process to one master, so the demo
makes one RosLink, after the master is up.
"""
import math
import threading
import time

import actionlib
import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import MapMetaData, Odometry, Path

TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException)
STATUS_NAMES = {value: name for name, value in vars(GoalStatus).items() if name.isupper() and isinstance(value, int)}


def yaw_of(quaternion):
    return 2.0 * math.atan2(quaternion.z, quaternion.w)


class RosLink:
    def __init__(self):
        rospy.init_node("turtlebot3c_demo", anonymous=True, disable_signals=True)
        self.lock = threading.Lock()
        self.truth = None           # (time, x, y, yaw) in the world frame
        self.truth_history = []
        self.recording = False
        self.plans = []             # (time, [(x, y), ...]) of /move_base/plan, map frame
        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.key_vel = rospy.Publisher("key_vel", Twist, queue_size=1)
        self.initial_pose = rospy.Publisher("initialpose", PoseWithCovarianceStamped, queue_size=1, latch=True)
        rospy.Subscriber("/sim/ground_truth", Odometry, self._on_truth, queue_size=5)
        self.amcl_poses = []        # (time, x, y) of /amcl_pose
        self.map_updates = []       # times /map_metadata came (SLAM publishes it with every map)
        rospy.Subscriber("/map_metadata", MapMetaData, self._on_map_metadata, queue_size=5)
        rospy.Subscriber("/move_base/plan", Path, self._on_plan, queue_size=5)
        rospy.Subscriber("/amcl_pose", PoseWithCovarianceStamped, self._on_amcl_pose, queue_size=5)

    def _on_truth(self, message):
        pose = message.pose.pose
        sample = (time.monotonic(), pose.position.x, pose.position.y, yaw_of(pose.orientation))
        with self.lock:
            self.truth = sample
            if self.recording:
                self.truth_history.append(sample)

    def _on_map_metadata(self, _message):
        with self.lock:
            self.map_updates.append(time.monotonic())

    def map_updated_since(self, since):
        with self.lock:
            return any(stamp >= since for stamp in self.map_updates)

    def _on_amcl_pose(self, message):
        position = message.pose.pose.position
        with self.lock:
            self.amcl_poses.append((time.monotonic(), position.x, position.y))

    def amcl_settled(self, since, pose, distance):
        """Whether AMCL's last estimate since `since` lies within `distance` of `pose` (a robot at
        rest gets one estimate after a new initial pose: the filter runs again only on motion)."""
        with self.lock:
            recent = [sample for sample in self.amcl_poses if sample[0] >= since][-1:]
        return bool(recent) and math.hypot(recent[0][1] - pose[0], recent[0][2] - pose[1]) <= distance

    def _on_plan(self, message):
        points = [(stamped.pose.position.x, stamped.pose.position.y) for stamped in message.poses]
        with self.lock:
            self.plans.append((time.monotonic(), points))

    # --- what the robot is doing ----------------------------------------------------

    def true_pose(self, max_age=0.5):
        with self.lock:
            sample = self.truth
        if sample is None or time.monotonic() - sample[0] > max_age:
            return None
        return sample[1:]

    def map_pose(self, timeout=0.5):
        """The robot's pose in `map` (SLAM's or AMCL's estimate), or None."""
        return self._pose_in("map", timeout)

    def odometry_tf(self, timeout=0.5):
        """The robot's pose in `odom` (the simulator's or the OpenCR driver's), or None."""
        return self._pose_in("odom", timeout)

    def _pose_in(self, frame, timeout):
        try:
            transform = self.tf_buffer.lookup_transform(frame, "base_footprint", rospy.Time(0),
                                                        rospy.Duration(timeout))
        except TF_ERRORS:
            return None
        translation = transform.transform.translation
        return translation.x, translation.y, yaw_of(transform.transform.rotation)

    def start_recording(self):
        with self.lock:
            self.truth_history = []
            self.recording = True

    def stop_recording(self):
        with self.lock:
            self.recording = False
            return list(self.truth_history)

    # --- driving ------------------------------------------------------------------------

    def drive(self, linear, angular):
        twist = Twist()
        twist.linear.x, twist.angular.z = linear, angular
        self.key_vel.publish(twist)

    def has_key_vel_listener(self):
        return self.key_vel.get_num_connections() > 0

    def follow(self, controller, timeout, period=0.1, on_step=None):
        """Publish controller.command(true pose) on key_vel at 10 Hz until it is done; True if it finished."""
        deadline = time.monotonic() + timeout
        next_tick = time.monotonic()
        self.stale_ticks = 0
        try:
            while time.monotonic() < deadline:
                pose = self.true_pose()
                self.stale_ticks += pose is None
                command = (0.0, 0.0) if pose is None else controller.command(pose)
                if command is None:
                    return True
                self.drive(*command)
                if on_step is not None and pose is not None:
                    on_step(pose)
                next_tick += period
                time.sleep(max(0.0, next_tick - time.monotonic()))
            return False
        finally:
            self.drive(0.0, 0.0)

    # --- navigation ---------------------------------------------------------------------

    def set_initial_pose(self, pose, sigma_xy=0.1, sigma_yaw=0.1):
        message = PoseWithCovarianceStamped()
        message.header.frame_id = "map"
        message.header.stamp = rospy.Time.now()
        message.pose.pose.position.x, message.pose.pose.position.y = pose[0], pose[1]
        message.pose.pose.orientation.z, message.pose.pose.orientation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
        covariance = [0.0] * 36
        covariance[0] = covariance[7] = sigma_xy ** 2
        covariance[35] = sigma_yaw ** 2
        message.pose.covariance = covariance
        self.initial_pose.publish(message)

    def initial_pose_listened(self):
        return self.initial_pose.get_num_connections() > 0

    def move_base_client(self, timeout):
        client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
        if not client.wait_for_server(rospy.Duration(timeout)):
            raise TimeoutError(f"the move_base action server did not appear within {timeout:.0f} s")
        return client

    def send_goal(self, client, goal, timeout):
        """Send a goal (x, y, yaw in map) and wait; (status name, status text, seconds)."""
        message = MoveBaseGoal()
        message.target_pose = PoseStamped()
        message.target_pose.header.frame_id = "map"
        message.target_pose.header.stamp = rospy.Time.now()
        message.target_pose.pose.position.x, message.target_pose.pose.position.y = goal[0], goal[1]
        message.target_pose.pose.orientation.z = math.sin(goal[2] / 2)
        message.target_pose.pose.orientation.w = math.cos(goal[2] / 2)
        started = time.monotonic()
        client.send_goal(message)
        if not client.wait_for_result(rospy.Duration(timeout)):
            client.cancel_goal()
            return "TIMEOUT", f"no result within {timeout:.0f} s", time.monotonic() - started
        return STATUS_NAMES.get(client.get_state(), str(client.get_state())), client.get_goal_status_text(), \
            time.monotonic() - started

    def plans_since(self, since):
        with self.lock:
            return [points for stamp, points in self.plans if stamp >= since and points]

    def shutdown(self):
        self.drive(0.0, 0.0)
        rospy.signal_shutdown("demo finished")
