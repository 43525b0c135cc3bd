#!/bin/bash
# mapping's post-stop-command: give the map save_map.sh just saved a dated name
# and make it the current map (current_map.yaml, a link navigation reads).
# The session's recording (new_map.bag, written by the mapping launch) gets the
# same dated name, so a map and the data it was made from stay together.
#
# Every map is kept. The link is replaced by rename(2), so current_map.yaml is
# always either the previous map or the new one, never missing or half-written.
# When no new map was saved, the previous current map stays. When the owner
# chose a map (snap set turtlebot3c map=NAME), the new map is kept and listed
# but that choice stays current; with map=latest (the default) it becomes current.
set -eu

map_dir="$SNAP_COMMON/maps"
new_yaml="$map_dir/new_map.yaml"
new_pgm="$map_dir/new_map.pgm"
new_bag="$map_dir/new_map.bag"
current="$map_dir/current_map.yaml"

# The map folder's lock (the maps app and the configure hook take it too): the
# new map is named and made current while no map is renamed, removed or chosen.
mkdir -p "$map_dir"
exec 9>>"$map_dir/.lock"
flock 9

# A name no other map or recording has, even for two saves within one second.
unused_name() {
  local stamp name suffix=1
  stamp="$(date +%Y-%m-%d_%H-%M-%S)"
  name="$stamp"
  while [ -e "$map_dir/$name.yaml" ] || [ -e "$map_dir/$name.pgm" ] || [ -e "$map_dir/$name.bag" ] ||
    [ -e "$map_dir/$name.bag.active" ]; do
    suffix=$((suffix + 1))
    name="${stamp}_${suffix}"
  done
  echo "$name"
}

# rosbag leaves <bag>.active when it was not closed cleanly; keep that too (rosbag reindex repairs it).
keep_recording() {
  local name="$1"
  if [ -f "$new_bag" ]; then
    mv -- "$new_bag" "$map_dir/$name.bag"
    echo "install_last_map: the session's recording is $map_dir/$name.bag"
  elif [ -f "$new_bag.active" ]; then
    mv -- "$new_bag.active" "$map_dir/$name.bag.active"
    echo "install_last_map: the session's recording was not closed cleanly: $map_dir/$name.bag.active" \
      "(repair it with rosbag reindex)" >&2
  fi
}

if [ ! -f "$new_yaml" ] || [ ! -f "$new_pgm" ]; then
  if [ -e "$current" ]; then
    echo "install_last_map: no new map was saved; the current map stays $(readlink -- "$current" || echo "$current")" >&2
  else
    echo "install_last_map: no new map was saved, and there is no current map yet" >&2
  fi
  keep_recording "$(unused_name)"
  exit 0
fi

name="$(unused_name)"

# The dated YAML names its image relatively, so the folder can move.
sed "s|^image:.*|image: $name.pgm|" "$new_yaml" >"$map_dir/.$name.yaml.tmp"
mv -- "$new_pgm" "$map_dir/$name.pgm"
sync -- "$map_dir/.$name.yaml.tmp" "$map_dir/$name.pgm"
mv -- "$map_dir/.$name.yaml.tmp" "$map_dir/$name.yaml"
rm -f -- "$new_yaml"
keep_recording "$name"

chosen="$(snapctl get map)"
case "$chosen" in
  "" | latest) ;;
  *)
    if [ -e "$current" ]; then
      sync -- "$map_dir"
      echo "install_last_map: the new map is saved as $map_dir/$name.yaml; the current map stays" \
        "'$chosen' (chosen with map=$chosen). To use the new one: sudo snap set $SNAP_INSTANCE_NAME map=$name" \
        "(or map=latest to always use the newest)"
      exit 0
    fi
    ;;
esac

ln -sfn -- "$name.yaml" "$map_dir/.current_map.yaml.tmp"
mv -fT -- "$map_dir/.current_map.yaml.tmp" "$current"
sync -- "$map_dir"
echo "install_last_map: $map_dir/$name.yaml is now the current map"
