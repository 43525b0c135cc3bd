#!/bin/bash
# The core daemon: the robot's drivers (or, with simulation=true, only the
# robot model) configured from the snap's options.
set -eu

simulation="$(snapctl get simulation)"
model="$(snapctl get turtlebot3-model)"
lds_model="$(snapctl get lds-model)"
opencr_port="$(snapctl get opencr-port)"
lds_port="$(snapctl get lds-port)"

case "$simulation" in
  true | 1) simulation=true ;;
  *) simulation=false ;;
esac

# Nodes that read the upstream TurtleBot3 variables see the same choice.
export TURTLEBOT3_MODEL="$model"
export LDS_MODEL="$lds_model"

# The master is the roscore app's: wait for it (bounded), and never start one (roslaunch_joining.py).
exec wait_for_master.sh roslaunch_joining.py --wait turtlebot3c_bringup turtlebot3c_bringup.launch \
  "simulation:=$simulation" "model:=$model" "lds_model:=$lds_model" \
  "opencr_port:=$opencr_port" "lds_port:=$lds_port"
