#!/bin/bash
# mapping's stop-command: save the map SLAM has built so far as
# $SNAP_COMMON/maps/new_map.{pgm,yaml}, for install_last_map.sh to install.
#
# The map is written in a private folder and moved in only when complete
# (image first, YAML last), so new_map.yaml is never half-written.
set -eu

map_dir="$SNAP_COMMON/maps"
mkdir -p "$map_dir"
# Left by a save that was killed (stop-timeout, power loss): never a complete map.
rm -rf -- "$map_dir"/.saving.*
work="$(mktemp -d "$map_dir/.saving.XXXXXX")"
trap 'rm -rf -- "$work"' EXIT

# A master that crashed is back within seconds (the roscore app): wait for it rather than lose
# the map, but not for ever (SLAM's map cannot be had without a master).
if ! ROS_MASTER_WAIT="${SAVE_MASTER_WAIT:-30}" "$(dirname -- "$0")/wait_for_master.sh"; then
  echo "save_map: the map could not be saved: no ROS master to get it from" >&2
  exit 1
fi
# First the refinement remap_bag runs at the end of a bag, on this session's keyframes: the map
# saved is the sharper one. Bounded, within mapping's stop-timeout: past it, or when SLAM does
# not answer, the map is saved as mapped. A `rosservice call` waiting for an answer outlives
# SIGTERM and SIGINT: only the KILL after it ends it.
refine_timeout="${SAVE_REFINE_TIMEOUT:-150}"
refined="$(timeout --kill-after=5 "$refine_timeout" rosservice call /refine_map 2>&1)" || true
if printf '%s\n' "$refined" | grep -q '^success: True'; then
  echo "save_map: $(printf '%s\n' "$refined" | sed -n 's/^message: "*\([^"]*\)"*$/\1/p')"
else
  echo "save_map: the map is saved unrefined: SLAM's refine_map gave no refined map within" \
    "${refine_timeout} s${refined:+: $(printf '%s' "$refined" | tr '\n' ' ')}" >&2
fi
if ! rosrun turtlebot3c_maps map_saver -f "$work/map"; then
  echo "save_map: the map could not be saved (see the map_saver message above)" >&2
  exit 1
fi
for file in "$work/map.pgm" "$work/map.yaml"; do
  if [ ! -s "$file" ]; then
    echo "save_map: map_saver reported success but wrote no $(basename -- "$file")" >&2
    exit 1
  fi
done

sync -- "$work/map.pgm" "$work/map.yaml"
mv -f -- "$work/map.pgm" "$map_dir/new_map.pgm"
mv -f -- "$work/map.yaml" "$map_dir/new_map.yaml"
echo "save_map: map saved as $map_dir/new_map.yaml"
