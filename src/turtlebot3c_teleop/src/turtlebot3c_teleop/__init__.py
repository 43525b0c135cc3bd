"""Teleoperation for turtlebot3c: keyboard, joystick, and the motion watchdog.

The modules here import no rospy; the executables in `nodes/` wrap them.
"""
