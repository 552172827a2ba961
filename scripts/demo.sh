#!/usr/bin/env bash
# The main job: installs what is missing, builds, and runs the built-in garment scene headless
# (or the scene file given as an argument), writing OBJ frames under out/.
# Any further arguments go to costume_sim (see: build/sim_core/app/costume_sim --help).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
exec build/sim_core/app/costume_sim "$@"
