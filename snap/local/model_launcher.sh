#!/bin/bash
# roslaunch PACKAGE FILE [ARG:=VALUE...] with model:= set from the
# `turtlebot3-model` option, so limits match the robot (not burger's by default).
#
#   model_launcher.sh PACKAGE LAUNCH_FILE [ARG:=VALUE...]
set -eu

if [ "$#" -lt 2 ]; then
  echo "usage: model_launcher.sh PACKAGE LAUNCH_FILE [ARG:=VALUE...]" >&2
  exit 2
fi
package="$1"
launch_file="$2"
shift 2

model="$(snapctl get turtlebot3-model)"
export TURTLEBOT3_MODEL="$model"
# The master is the roscore app's: wait for it (bounded), and never start one (roslaunch_joining.py).
exec wait_for_master.sh roslaunch_joining.py --wait "$package" "$launch_file" "model:=$model" "$@"
