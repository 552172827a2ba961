#!/usr/bin/env bash
# Installs the Debian 12 packages the project builds with, if any is missing.
# Safe to run again: it does nothing when everything is there.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libsuitesparse-dev libopenblas0-serial   # sim_core: Eigen, CHOLMOD (+ fast BLAS)
  libassimp-dev libtomlplusplus-dev                      # assets: meshes, scene files
  libcli11-dev nlohmann-json3-dev libgtest-dev           # programs, benchmarks, tests
  libbullet-dev                                          # collision (avatar issue)
  liblcm-dev liblcm-bin libglib2.0-dev liblcm-java default-jdk-headless  # processes
  qt6-base-dev libqt6opengl6-dev libgl-dev libosmesa6-dev xvfb xauth     # frontend
  qt6-wayland                                            # the GUI on a Wayland-only desktop
  libsqlite3-dev libpq-dev                               # database
  postgresql                                             # catalogue tests start their own server
  libpng-dev                                             # render: thumbnails as PNG
  zlib1g-dev                                             # haptic server: /proc/config.gz
)

missing=()
for package in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" ||
    missing+=("$package")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "Installing missing packages: ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "error: need root (or sudo) to apt-get install" >&2; exit 1; }
  sudo="sudo"
fi
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
