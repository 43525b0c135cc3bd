#!/bin/bash
# turtlebot3c.status: a line per part of the robot, working or not, with the one
# thing to do. Any user may run it: it changes nothing and needs no root.
set -eu

exec "$SNAP/opt/ros/noetic/lib/turtlebot3c_status/status" "$@"
