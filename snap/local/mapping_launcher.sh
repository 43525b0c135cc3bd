#!/bin/bash
# The mapping daemon: hand the robot to the keyboard, then run SLAM.
#
# The mux is selected here, not in the app's command-chain: the chain also
# wraps the stop-command, and saving the map must not depend on teleop being up.
set -eu

# The session's bag goes beside the maps; install_last_map.sh gives it its map's name.
map_dir="$SNAP_COMMON/maps"
mkdir -p "$map_dir"

export MUX_INPUT=key_vel
exec wait_for_master.sh mux_select.sh model_launcher.sh turtlebot3c_slam turtlebot3c_mapping.launch "bag:=$map_dir/new_map.bag"
