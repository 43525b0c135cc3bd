"""The SLAM node's map -> odom transform does not wait for the SLAM: refine_map holds the SLAM for
seconds on a long session, and tf in the map frame must not lapse meanwhile."""
from testkit import ros_harness

# The shipped node, its SLAM held from the start as refine_map holds it while it refines.
HOLDING_THE_SLAM = """
from importlib.machinery import SourceFileLoader
import roslib.packages, rospy
slam_node = SourceFileLoader("slam_node", roslib.packages.find_node("turtlebot3c_slam", "slam")[0]).load_module()
rospy.init_node("turtlebot3_slam_gmapping")
node = slam_node.SlamNode(slam_node.SlamConfig())
node.lock.acquire()
print("the SLAM is held", flush=True)
rospy.spin()
"""


def map_to_odom(message):
    return [each for each in message["transforms"]
            if each["header"]["frame_id"] == "map" and each["child_frame_id"] == "odom"]


def test_map_to_odom_goes_on_while_the_slam_is_held(ros_master):
    holder = ros_master.start([ros_harness.python(), "-c", HOLDING_THE_SLAM], name="slam_held")
    ros_harness.wait_until(lambda: "the SLAM is held" in holder.log_text(), 60,
                           f"the SLAM node did not start: {holder.tail()}")
    probe = ros_master.probe
    probe.wait_for_message("/tf", "tf2_msgs/TFMessage", timeout=30)
    start = probe.count("/tf")

    def published_since_held():
        return [each for message in probe.messages("/tf", start) for each in map_to_odom(message)]
    ros_harness.wait_until(lambda: len(published_since_held()) >= 5, 20,
                           "map -> odom stopped while the SLAM was held")
    translation = published_since_held()[-1]["transform"]["translation"]
    assert (translation["x"], translation["y"]) == (0.0, 0.0)  # no scan yet: map and odom coincide
