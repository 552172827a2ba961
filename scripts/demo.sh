#!/usr/bin/env bash
# The main job: installs what is missing and builds; then
#  - with a display (DISPLAY or WAYLAND_DISPLAY set): the workstation — the Qt GUI, which starts
#    the simulation server and the haptic server with the chosen device as its child processes
#    and stops them when its window closes (docs/frontend.md);
#  - without a display, or with --headless, or with an option only the headless program knows
#    (--out, --duration, ...): the headless run of the built-in garment scene (or the scene file
#    given), writing OBJ frames under out/ (see: build/sim_core/app/costume_sim --help).
# Workstation options: --device simulated|mouse|openhaptics|cybergrasp|none (default mouse),
# --builtin NAME, --scene FILE or a scene file as the first argument, --editing,
# --lcm-url URL, --radius M.
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${1:-}" == "--help" || "${1:-}" == "-h" ]]; then
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
  echo "Headless options:"
  bash scripts/build.sh >/dev/null
  exec build/sim_core/app/costume_sim --help
fi

headless=0
[[ -z "${DISPLAY:-}" && -z "${WAYLAND_DISPLAY:-}" ]] && headless=1
gui_args=()
sim_args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --headless) headless=1; shift ;;
    --device|--builtin|--scene|--lcm-url|--radius)
      [[ $# -ge 2 ]] || { echo "demo.sh: $1 needs a value" >&2; exit 2; }
      gui_args+=("$1" "$2"); sim_args+=("$1" "$2"); shift 2 ;;
    --editing) gui_args+=("$1"); shift ;;
    --no-frames|--quiet) headless=1; sim_args+=("$1"); shift ;;   # headless flags
    -*)  # an option of the headless program, with its value
      headless=1; sim_args+=("$1"); shift
      if [[ $# -gt 0 && "$1" != -* ]]; then sim_args+=("$1"); shift; fi ;;
    *) gui_args+=(--scene "$1"); sim_args+=("$1"); shift ;;
  esac
done

bash scripts/build.sh
if [[ $headless -eq 1 ]]; then
  # costume_sim takes the scene file positionally and knows no --device/--lcm-url/--radius.
  args=()
  set -- "${sim_args[@]+"${sim_args[@]}"}"
  while [[ $# -gt 0 ]]; do
    case "$1" in
      --device|--lcm-url|--radius) shift 2 ;;
      --scene) args+=("$2"); shift 2 ;;
      *) args+=("$1"); shift ;;
    esac
  done
  exec build/sim_core/app/costume_sim "${args[@]+"${args[@]}"}"
fi
exec build/frontend/costume_designer "${gui_args[@]+"${gui_args[@]}"}"
