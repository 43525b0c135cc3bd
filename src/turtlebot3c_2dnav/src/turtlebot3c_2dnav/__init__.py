"""Mapping and navigation for turtlebot3c: SLAM, map files, localisation, planning, control.

The algorithms are plain numpy modules with no rospy; the nodes wrap them.
"""
