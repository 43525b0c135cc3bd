#!/bin/bash
# Command-chain: point ROS at the master named by the `ros-master-host` option.
#
# The ros1-launch chain step runs before this one and, by sourcing the
# workspace, has already set ROS_MASTER_URI to roslaunch's default
# http://localhost:11311; only that default (or nothing) is replaced, so a URI
# given on purpose (/etc/environment, the caller's shell) wins.
set -eu

master_host="$(snapctl get ros-master-host)"
this_host="$(uname -n)"

if [ -n "$master_host" ]; then
  if [ -z "${ROS_MASTER_URI:-}" ] || [ "$ROS_MASTER_URI" = "http://localhost:11311" ]; then
    export ROS_MASTER_URI="http://${master_host}:11311"
    export TURTLEBOT3C_URI_FROM_OPTION=1 # the roscore app follows the option when it changes
  fi
  # Other machines reach our nodes by this name. When the master runs here,
  # the master's name is ours; otherwise use our own mDNS name, not the
  # master's (which would send the master's traffic back to itself).
  if [ -z "${ROS_HOSTNAME:-}" ] && [ -z "${ROS_IP:-}" ]; then
    case "$master_host" in
      localhost | "$this_host" | "$this_host.local") export ROS_HOSTNAME="$master_host" ;;
      *) export ROS_HOSTNAME="$this_host.local" ;;
    esac
  fi
fi

exec "$@"
