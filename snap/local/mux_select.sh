#!/bin/bash
# Select the velocity multiplexer's input, then run the given command.
#
#   mux_select.sh [--input NAME] [COMMAND [ARG...]]
#
# NAME defaults to $MUX_INPUT (set in the app's `environment:`, since a
# command-chain entry cannot take arguments): key_vel, joy_vel or nav_vel.
# Teleop may still be starting, so /mux/select is awaited for
# $MUX_SELECT_TIMEOUT seconds (default 30); after that it fails clearly
# rather than running a source the robot does not listen to.
set -eu

input="${MUX_INPUT:-}"
if [ "${1:-}" = "--input" ]; then
  input="${2:-}"
  shift 2 || shift $#
fi
timeout_s="${MUX_SELECT_TIMEOUT:-30}"

case "$input" in
  key_vel | joy_vel | nav_vel) ;;
  *)
    echo "mux_select: unknown mux input '$input' (allowed: key_vel, joy_vel, nav_vel)" >&2
    exit 2
    ;;
esac

# A nested mux_select.sh (a post-stop-command run through this chain) makes
# the selection that counts; selecting here first would only flip the mux.
if [ "$#" -gt 0 ] && [ "$(basename -- "$1")" = "mux_select.sh" ]; then
  exec "$@"
fi

deadline=$(($(date +%s) + timeout_s))
# A `rosservice call` waiting for an answer (a hung mux) outlives SIGTERM: the KILL after it ends it.
until output="$(timeout --kill-after=5 15 rosservice call /mux/select "topic: '$input'" 2>&1)"; do
  if [ "$(date +%s)" -ge "$deadline" ]; then
    # From another machine the usual cause is a wrong ros-master-host, not a stopped teleop: say which.
    if ! timeout 10 rosnode list >/dev/null 2>&1; then
      echo "mux_select: could not select '$input': no ROS master answers at ${ROS_MASTER_URI:-(unset)}" \
        "within ${timeout_s} s. Is the robot on, and is ros-master-host right" \
        "(snap get turtlebot3c ros-master-host; sudo snap set turtlebot3c ros-master-host=<robot name or address>)?" >&2
      exit 1
    fi
    echo "mux_select: could not select '$input': /mux/select did not answer within ${timeout_s} s" \
      "(is the teleop daemon running? sudo snap start turtlebot3c.teleop). Last error: $output" >&2
    exit 1
  fi
  sleep 1
done
echo "mux_select: velocity input is now '$input' (${output})"

if [ "$#" -gt 0 ]; then
  exec "$@"
fi
