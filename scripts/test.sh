#!/usr/bin/env bash
# Every test: installs what is missing, builds, runs ctest (labels unit, slow, integration).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j "${JOBS:-2}" --timeout 1200
