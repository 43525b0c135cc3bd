"""Maps for turtlebot3c: map_server's file format, the maps folder, and the OccupancyGrid messages.

The modules here import no rospy; map_server, map_saver and the snap's maps app in `nodes/` wrap them.
"""
