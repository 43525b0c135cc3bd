#!/usr/bin/env python3
"""roslaunch that joins the ROS master and never starts one: the roscore app runs the master.

    roslaunch_joining.py [roslaunch arguments...]

`roslaunch --wait` waits for a master only once, as it starts; if the master dies before
roslaunch gets to it (a crash, the roscore app restarted), roslaunch would start a master of
its own, which then fights the roscore app's for the port. Here it stops instead, with one
line naming the URI; the daemon's restart runs wait_for_master.sh again.
"""
import roslaunch
import roslaunch.launch
from roslaunch.core import RLException


def refuse_to_start_a_master(master, *_args):
    raise RLException(f"no ROS master answers at {master.uri} any more; this launch never starts one "
                      "(turtlebot3c.roscore does): stopping, to start again once it answers")


roslaunch.launch.validate_master_launch = refuse_to_start_a_master
roslaunch.main()
