"""Bringup of the TurtleBot3 hardware: the OpenCR board and the LDS LIDARs.

Protocol and decoding modules here import no rospy; the nodes wrap them.
"""
