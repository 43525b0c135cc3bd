#!/bin/bash
# mapping's post-stop-command: give the map save_map.sh just saved a dated name
# and make it the current map (current_map.yaml, a link navigation reads).
#
# Every map is kept. The link is replaced by rename(2), so current_map.yaml is
# always either the previous map or the new one, never missing or half-written.
# When no new map was saved, the previous current map stays.
set -eu

map_dir="$SNAP_USER_COMMON/map"
new_yaml="$map_dir/new_map.yaml"
new_pgm="$map_dir/new_map.pgm"
current="$map_dir/current_map.yaml"

if [ ! -f "$new_yaml" ] || [ ! -f "$new_pgm" ]; then
  if [ -e "$current" ]; then
    echo "install_last_map: no new map was saved; the current map stays $(readlink -- "$current" || echo "$current")" >&2
  else
    echo "install_last_map: no new map was saved, and there is no current map yet" >&2
  fi
  exit 0
fi

# A name no other map has, even for two maps saved within the same second.
stamp="$(date +%Y-%m-%d_%H-%M-%S)"
name="$stamp"
suffix=1
while [ -e "$map_dir/$name.yaml" ] || [ -e "$map_dir/$name.pgm" ]; do
  suffix=$((suffix + 1))
  name="${stamp}_${suffix}"
done

# The dated YAML names its image relatively, so the folder can move.
sed "s|^image:.*|image: $name.pgm|" "$new_yaml" >"$map_dir/.$name.yaml.tmp"
mv -- "$new_pgm" "$map_dir/$name.pgm"
sync -- "$map_dir/.$name.yaml.tmp" "$map_dir/$name.pgm"
mv -- "$map_dir/.$name.yaml.tmp" "$map_dir/$name.yaml"
rm -f -- "$new_yaml"

ln -sfn -- "$name.yaml" "$map_dir/.current_map.yaml.tmp"
mv -fT -- "$map_dir/.current_map.yaml.tmp" "$current"
sync -- "$map_dir"
echo "install_last_map: $map_dir/$name.yaml is now the current map"
