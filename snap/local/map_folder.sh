#!/bin/sh
# Sourced by the hooks (POSIX sh, dash on core20): the map folder every app uses.
# A map is NAME.yaml there with its image NAME.pgm; current_map.yaml links to
# the current one and new_map.* are files in transit, not maps.
# shellcheck shell=sh

maps_dir="${maps_dir:-$SNAP_COMMON/maps}"

# Every map's name, one per line, sorted.
map_names() {
  for yaml in "$maps_dir"/*.yaml; do
    [ -f "$yaml" ] || continue
    name="${yaml##*/}"
    name="${name%.yaml}"
    case "$name" in
      current_map | new_map) ;;
      *) printf '%s\n' "$name" ;;
    esac
  done
}

# The map added last: its image is the newest (saving and importing date it;
# renaming and migrating keep the date). Empty when there is no map.
newest_map() {
  newest=""
  for yaml in "$maps_dir"/*.yaml; do
    [ -f "$yaml" ] || continue
    name="${yaml##*/}"
    name="${name%.yaml}"
    case "$name" in
      current_map | new_map) continue ;;
    esac
    # shellcheck disable=SC3013 # dash, core20's /bin/sh, has -nt
    if [ -z "$newest" ] || [ "$maps_dir/$name.pgm" -nt "$maps_dir/$newest.pgm" ]; then
      newest="$name"
    fi
  done
  printf '%s' "$newest"
}

# The map current_map.yaml links to (empty when none).
current_map() {
  target="$(readlink "$maps_dir/current_map.yaml" || true)"
  printf '%s' "${target%.yaml}"
}

# Make NAME the current map in one rename(2), so the link is never missing or half-written.
make_current() {
  ln -sfn -- "$1.yaml" "$maps_dir/.current_map.yaml.tmp"
  mv -fT -- "$maps_dir/.current_map.yaml.tmp" "$maps_dir/current_map.yaml"
  sync -- "$maps_dir"
}

# The guide's map folder, root's $SNAP_USER_COMMON/map (the upstream snap's, which
# scripts rely on: .../common/map/current_map.yaml), as a link to the maps folder.
# Made when nothing is there; an old folder of maps is left to migrate_maps.sh.
link_user_map_folder() {
  mkdir -p "$maps_dir"
  if [ ! -e "$SNAP_USER_COMMON/map" ] && [ ! -L "$SNAP_USER_COMMON/map" ]; then
    mkdir -p "$SNAP_USER_COMMON"
    ln -s "$maps_dir" "$SNAP_USER_COMMON/map"
  fi
}
