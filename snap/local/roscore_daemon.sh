#!/bin/bash
# The roscore daemon: the one ROS master of the robot, which every other app waits for.
#
# It runs `roscore` on the port of $ROS_MASTER_URI when that URI names this
# machine, and starts it again at once if it ends (a crashed master); the other
# daemons' nodes register with the new one by themselves. When the URI names
# another machine (ros-master-host), it runs no master and says so. It follows
# ros-master-host by itself: the configure hook never restarts it, so no
# `snap set` takes the master from under the nodes. A master already answering
# at the URI (one started by hand) is used, not fought: ours starts when it ends. A port
# held by something else is waited for, with one line saying so.
set -eu

# shellcheck disable=SC1091 # snap/local/ros_master.sh, in the snap's usr/bin
. "$SNAP/usr/bin/ros_master.sh"

CHECK_EVERY=5 # s between looks at ros-master-host and at a master that is not ours

given_uri="${ROS_MASTER_URI:-http://localhost:11311}"
# ros_network.sh says whether the URI comes from ros-master-host (else it was given on purpose).
current_uri() {
  if [ -n "${TURTLEBOT3C_URI_FROM_OPTION:-}" ]; then
    printf 'http://%s:11311' "$(snapctl get ros-master-host)"
  else
    printf '%s' "$given_uri"
  fi
}

roscore_pid=""
said=""
say_once() {
  if [ "$said" != "$1" ]; then
    echo "roscore: $1"
    said="$1"
  fi
}

stop_roscore() {
  if [ -n "$roscore_pid" ]; then
    kill -INT "$roscore_pid" 2>/dev/null || true
    wait "$roscore_pid" 2>/dev/null || true
    roscore_pid=""
  fi
}
trap 'stop_roscore; exit 0' TERM INT

uri="$(current_uri)"
while :; do
  if [ -n "$roscore_pid" ] && ! kill -0 "$roscore_pid" 2>/dev/null; then
    status=0
    wait "$roscore_pid" || status=$?
    roscore_pid=""
    said=""
    echo "roscore: the ROS master at $uri ended (status $status); starting it again" >&2
  fi
  if [ -z "$roscore_pid" ]; then
    uri="$(current_uri)"
    host="$(uri_host "$uri")"
    port="$(uri_port "$uri")"
    if ! host_is_here "$host"; then
      say_once "the ROS master is on another machine ($uri, ros-master-host=$(snapctl get ros-master-host)): no master runs here"
    elif master_answers "$uri"; then
      say_once "a ROS master not started by this daemon already answers at $uri: using it (ours starts when it ends)"
    elif ! port_is_free "$port"; then
      say_once "port $port of this machine is taken by a program that is not a ROS master: the master starts when it is free"
    else
      roscore -p "$port" &
      roscore_pid="$!"
      said=""
      echo "roscore: the ROS master runs at $uri (pid $roscore_pid)"
    fi
  fi
  # Wait, noticing at once (within 1 s) that our master ended; look at the option every CHECK_EVERY s.
  for _ in $(seq "$CHECK_EVERY"); do
    sleep 1 &
    wait "$!" || true
    if [ -n "$roscore_pid" ] && ! kill -0 "$roscore_pid" 2>/dev/null; then
      break
    fi
  done
  if [ -n "$roscore_pid" ]; then
    new_uri="$(current_uri)"
    if [ "$new_uri" != "$uri" ] && ! host_is_here "$(uri_host "$new_uri")"; then
      echo "roscore: ros-master-host now names another machine ($new_uri): stopping the master here"
      stop_roscore
    fi
  fi
done
