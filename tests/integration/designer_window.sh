#!/bin/sh
# Runs the real-window test of the GUI ($1) under Xvfb inside a private network namespace
# (multicast on lo only). Exit 77 (skipped) without xvfb-run or a namespace.
command -v xvfb-run >/dev/null 2>&1 || { echo "xvfb-run not found: skipped"; exit 77; }
unshare -n true 2>/dev/null || { echo "no network namespace: skipped"; exit 77; }
exec unshare -n sh -c '
  ip link set lo up && ip route add 224.0.0.0/4 dev lo || exit 1
  export COSTUME_IN_NETNS=1 QT_QPA_PLATFORM=xcb
  exec xvfb-run -a -s "-screen 0 1280x800x24" "$0"
' "$1"
