#!/bin/sh
# costume_sim writes a scene's frames in a folder of --out named after the scene. The name is
# free text in the scene file: "../../escaped" once wrote the frames two folders above --out.
# Usage: frames_stay_in_out.sh <costume_sim> <hang.toml>
set -u
program=$1
scene=$2
dir=$(mktemp -d) || exit 1
trap 'rm -rf "$dir"' EXIT
sed 's|^name = "hang"|name = "../../escaped"|' "$scene" > "$dir/scene.toml"
grep -q '^name = "../../escaped"' "$dir/scene.toml" || { echo "the scene's name was not set"; exit 1; }
"$program" "$dir/scene.toml" --out "$dir/out/a" --duration 0.05 --quiet || exit 1
if [ -e "$dir/escaped" ]; then
  echo "frames written outside --out: $(ls "$dir/escaped")"
  exit 1
fi
[ -f "$dir/out/a/.._.._escaped/frame_0001.obj" ] || { echo "no frames in --out:"; find "$dir"; exit 1; }
echo "frames stayed in --out"
