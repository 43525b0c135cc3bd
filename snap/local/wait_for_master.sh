#!/bin/bash
# Wait for the ROS master at $ROS_MASTER_URI, then run the given command.
#
#   wait_for_master.sh [COMMAND [ARG...]]
#
# The master is the roscore app's (or another machine's, with ros-master-host);
# no other app ever starts one. The wait is bounded: after $ROS_MASTER_WAIT
# seconds (default 60) it fails with one line naming the URI.
set -eu

# shellcheck disable=SC1091 # snap/local/ros_master.sh, in the snap's usr/bin
. "$(dirname -- "$0")/ros_master.sh"

uri="${ROS_MASTER_URI:-http://localhost:11311}"
timeout_s="${ROS_MASTER_WAIT:-60}"

if ! master_answers "$uri"; then
  echo "wait_for_master: waiting up to ${timeout_s} s for the ROS master at $uri"
  deadline=$(($(date +%s) + timeout_s))
  until master_answers "$uri"; do
    if [ "$(date +%s)" -ge "$deadline" ]; then
      echo "wait_for_master: no ROS master answers at $uri after ${timeout_s} s; is turtlebot3c.roscore" \
        "running on that machine (snap services turtlebot3c), and is ros-master-host right" \
        "(snap get turtlebot3c ros-master-host)?" >&2
      exit 1
    fi
    sleep 0.5
  done
  echo "wait_for_master: the ROS master at $uri answers"
fi

if [ "$#" -gt 0 ]; then
  exec "$@"
fi
