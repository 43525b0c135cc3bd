#!/bin/bash
# Move every map from an old map folder into the new one (the post-refresh hook:
# root's $SNAP_USER_COMMON/map, where revisions before $SNAP_COMMON/maps kept them).
#
#   migrate_maps.sh OLD_FOLDER NEW_FOLDER
#
# Every file comes along: maps (YAML and image), session bags, files in transit.
# Nothing is lost if this is interrupted, and running it again finishes the job:
# each file first gets its new name (a hard link, or across file systems a
# complete copy renamed into place), images and bags before the YAML that makes
# them a map; current_map.yaml is set in the new folder before anything leaves
# the old one, and a file is deleted there only when its twin is in place. A
# name taken in the new folder by a different file is never overwritten: that
# map stays in the old folder, with a message. Once the old folder is empty it
# becomes a link to the new one, so a reverted (earlier) revision still finds
# every map, and saves new ones in the new folder.
set -eu

old_dir="$1"
new_dir="$2"

old_link="$old_dir.moved" # the link that replaces the old folder, made before the folder goes
if [ -L "$old_dir" ]; then
  exit 0 # migrated already
fi
if [ ! -e "$old_dir" ]; then
  if [ -L "$old_link" ]; then
    mv -T -- "$old_link" "$old_dir" # cut between removing the old folder and linking it
  fi
  exit 0
fi
mkdir -p "$new_dir"

say() {
  echo "migrate_maps: $*"
}

# The map a file belongs to (2026-01-02_03-04-05.bag.active -> 2026-01-02_03-04-05).
stem_of() {
  local name="$1"
  for suffix in .bag.active .yaml .pgm .bag; do
    if [ "${name%"$suffix"}" != "$name" ]; then
      printf '%s' "${name%"$suffix"}"
      return
    fi
  done
  printf '%s' "$name"
}

# The YAML as it is in the new folder: an image path into the old folder becomes relative.
migrated_yaml() {
  sed "s|^image: *\\([\"']\\{0,1\\}\\)$old_dir/|image: \\1|" "$1"
}

# Put file $1 of the old folder into the new one (a different file under its name was ruled out).
place() {
  local name="$1" source="$old_dir/$1" target="$new_dir/$1" staged="$new_dir/.$1.migrating"
  if [[ "$name" == *.yaml ]]; then
    migrated_yaml "$source" >"$staged"
    touch -r "$source" -- "$staged"
    if [ -e "$target" ] || [ -L "$target" ]; then
      local status=0
      cmp -s -- "$staged" "$target" || status=1
      rm -f -- "$staged"
      return "$status"
    fi
  else
    if [ -e "$target" ] || [ -L "$target" ]; then
      cmp -s -- "$source" "$target"
      return
    fi
    if ln -- "$source" "$target" 2>/dev/null; then
      return 0
    fi
    cp -p -- "$source" "$staged"
  fi
  sync -- "$staged"
  mv -T -- "$staged" "$target"
}

# Placed already (by this run or an interrupted one): the same content under the same name.
is_placed() {
  local name="$1"
  if [[ "$name" == *.yaml ]]; then
    cmp -s <(migrated_yaml "$old_dir/$name") "$new_dir/$name"
  else
    cmp -s -- "$old_dir/$name" "$new_dir/$name"
  fi
}

files=()
yamls=()
for path in "$old_dir"/*; do
  name="${path##*/}"
  if [ -L "$path" ] || [ ! -f "$path" ]; then
    continue # current_map.yaml (handled below) and anything that is not a plain file
  fi
  if [[ "$name" == *.yaml ]]; then
    yamls+=("$name")
  else
    files+=("$name")
  fi
done

# A name taken in the new folder by a different file keeps that file's whole map where it is.
clashes() {
  local name="$1" target="$new_dir/$1"
  if [ ! -e "$target" ] && [ ! -L "$target" ]; then
    return 1
  fi
  ! is_placed "$name"
}
declare -A clashed=()
for name in ${files[@]+"${files[@]}"} ${yamls[@]+"${yamls[@]}"}; do
  if clashes "$name"; then
    stem="$(stem_of "$name")"
    clashed[$stem]=1
    say "$new_dir/$name exists and differs from $old_dir/$name: map $stem stays in $old_dir" >&2
  fi
done

for name in ${files[@]+"${files[@]}"} ${yamls[@]+"${yamls[@]}"}; do
  if [ -z "${clashed[$(stem_of "$name")]:-}" ]; then
    place "$name"
  fi
done

# The current map stays current (unless the new folder already has one).
old_current="$(readlink -- "$old_dir/current_map.yaml" || true)"
old_current="${old_current##*/}"
if [ -n "$old_current" ] && [ ! -e "$new_dir/current_map.yaml" ] && [ -f "$new_dir/$old_current" ]; then
  ln -sfn -- "$old_current" "$new_dir/.current_map.yaml.tmp"
  mv -fT -- "$new_dir/.current_map.yaml.tmp" "$new_dir/current_map.yaml"
fi
sync -- "$new_dir"

# Only now does anything leave the old folder, and only what is in place.
for name in ${files[@]+"${files[@]}"} ${yamls[@]+"${yamls[@]}"}; do
  if [ -z "${clashed[$(stem_of "$name")]:-}" ] && is_placed "$name"; then
    rm -f -- "$old_dir/$name"
  fi
done
if [ -e "$new_dir/current_map.yaml" ] && [ -L "$old_dir/current_map.yaml" ] &&
  [ ! -e "$old_dir/$old_current" ]; then
  rm -f -- "$old_dir/current_map.yaml"
fi
# Left by saves that were killed midway: never a complete map.
rm -rf -- "$old_dir"/.saving.* "$old_dir/.current_map.yaml.tmp"

ln -sfn -- "$new_dir" "$old_link"
if rmdir -- "$old_dir" 2>/dev/null; then
  mv -T -- "$old_link" "$old_dir"
  say "the maps moved from $old_dir to $new_dir (the old folder is now a link to it)"
else
  rm -f -- "$old_link"
  say "the maps moved from $old_dir to $new_dir; what could not move stays in $old_dir:" \
    "$(find "$old_dir" -mindepth 1 -maxdepth 1 -printf '%f ')" >&2
fi
