#!/bin/bash
# The mapping daemon: hand the robot to the keyboard, then run SLAM.
#
# The mux is selected here, not in the app's command-chain: the chain also
# wraps the stop-command, and saving the map must not depend on teleop being up.
set -eu

export MUX_INPUT=key_vel
exec mux_select.sh model_launcher.sh turtlebot3c_2dnav turtlebot3c_mapping.launch
