#!/usr/bin/env bash
# Configures and builds the project (Release) into build/. Used by demo.sh and test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
# Two cores here: two jobs. Override with JOBS=n.
cmake --build build -j "${JOBS:-2}"
