#!/bin/bash
# The navigation daemon: localise and plan on the current map.
#
# Without a map there is nothing to navigate on: say so and exit 0, so the
# service stops instead of being restarted in a loop.
set -eu

map_file="$SNAP_COMMON/maps/current_map.yaml"

if [ ! -r "$map_file" ]; then
  echo "navigation: no map to navigate on: $map_file does not exist." \
    "Make one first: sudo snap start turtlebot3c.mapping, drive the robot around," \
    "then sudo snap stop turtlebot3c.mapping. Navigation is not started." >&2
  exit 0
fi

exec model_launcher.sh turtlebot3c_navigation turtlebot3c_navigation.launch "map_file:=$map_file"
