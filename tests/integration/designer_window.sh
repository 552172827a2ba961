#!/bin/sh
# Runs the real-window test of the GUI ($1) under Xvfb inside a private network namespace
# (multicast on lo only). Exit 77 (skipped) without xvfb-run or a namespace.
command -v xvfb-run >/dev/null 2>&1 || { echo "xvfb-run not found: skipped"; exit 77; }
exec env QT_QPA_PLATFORM=xcb sh "$(dirname "$0")/../support/in_netns.sh" \
    xvfb-run -a -s "-screen 0 1280x800x24" "$1"
