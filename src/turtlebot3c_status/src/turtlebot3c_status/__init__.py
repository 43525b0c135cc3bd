"""turtlebot3c.status: what works and what to do about what does not.

The modules here import no rospy: `snap_facts` and `master_facts` ask snapd and the
ROS master, `checks` judges every part from the facts, `report` prints them;
the `status` node in `nodes/` listens to the robot's topics and ties them together.
"""
