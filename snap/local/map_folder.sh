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

# Whether NAME is a complete map: NAME.yaml and NAME.pgm both regular files,
# not links (an interrupted save, import or migration leaves one without the
# other; a YAML without its own image is no map navigation could load).
is_complete_map() {
  case "$1" in
    "" | .* | current_map | new_map) return 1 ;;
  esac
  [ -f "$maps_dir/$1.yaml" ] && [ ! -L "$maps_dir/$1.yaml" ] &&
    [ -f "$maps_dir/$1.pgm" ] && [ ! -L "$maps_dir/$1.pgm" ]
}

# The map added last, among complete maps; empty when there is none. Added
# last: its image's modification time is the latest, to the nanosecond
# (saving and importing date it, renaming and migrating keep the date); of
# images dated alike, the name that sorts last in C order (dated names sort
# as their dates, NAME_2 after NAME). GNU find prints the times (core20 has
# it); test's -nt is not used: dash may compare whole seconds only, and it
# is false for a missing image, which kept a broken map "latest" for good.
newest_map() {
  find "$maps_dir/" -mindepth 1 -maxdepth 1 -type f -name '*.pgm' ! -name '.*' -printf '%T@ %f\n' |
    LC_ALL=C sort -k1,1n -k2 |
    while read -r _ image; do
      if is_complete_map "${image%.pgm}"; then
        printf '%s\n' "${image%.pgm}"
      fi
    done | tail -n 1
}

# Run the rest of the calling shell's work on the map folder holding its lock
# (flock(2) on .lock, the maps app's lock too), so that the current map is
# never chosen from, or pointed at, a map being renamed or removed. Released
# when the shell exits, or by unlock_map_folder.
lock_map_folder() {
  mkdir -p "$maps_dir"
  exec 9>>"$maps_dir/.lock"
  flock 9
}

unlock_map_folder() {
  exec 9>&-
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
