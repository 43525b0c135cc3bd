"""2D laser SLAM for turtlebot3c: scan-to-map tracking, a pose graph with loop closure, occupancy grids.

The modules here import no rospy; the slam node and the offline remap_bag tool in `nodes/` wrap them.
"""
