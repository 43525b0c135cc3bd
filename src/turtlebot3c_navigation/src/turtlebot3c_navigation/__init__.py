"""Navigation for turtlebot3c: AMCL localisation, costmaps, the global planner and the DWA controller.

The modules here import no rospy; the amcl and move_base nodes in `nodes/` wrap them.
"""
