#!/bin/sh
# The GUI owns its servers: costume_designer ($1) starts costume_sim_server and
# costume_haptic_server; SIGTERM to the GUI alone closes the window and stops both, and so does
# SIGKILL (the children have PR_SET_PDEATHSIG). Runs under Xvfb in private network and pid
# namespaces (only this test's processes are seen). Exit 77 (skipped) without xvfb-run or
# namespaces.
command -v xvfb-run >/dev/null 2>&1 || { echo "xvfb-run not found: skipped"; exit 77; }
unshare -n --pid --fork --mount-proc true 2>/dev/null || { echo "no namespaces: skipped"; exit 77; }
exec unshare -n --pid --fork --mount-proc sh -c '
  ip link set lo up && ip route add 224.0.0.0/4 dev lo || exit 1
  designer=$0
  # A scratch folder: the log, and a catalogue of its own (not the user'"'"'s).
  scratch=$(mktemp -d) || exit 1
  trap "rm -rf $scratch" EXIT
  export COSTUME_CATALOG="sqlite:$scratch/catalog.sqlite"
  servers() { ps -eo comm | grep -c "^costume_\(sim_ser\|haptic_\)"; }
  for signal in TERM KILL; do
    QT_QPA_PLATFORM=xcb xvfb-run -a -s "-screen 0 1280x800x24" "$designer" --device mouse \
        > $scratch/designer.log 2>&1 &
    n=0
    while [ "$(servers)" -lt 2 ] && [ $n -lt 300 ]; do sleep 0.1; n=$((n + 1)); done
    [ "$(servers)" -eq 2 ] || { echo "FAIL: the servers did not start"; cat $scratch/designer.log; exit 1; }
    sleep 2
    gui=$(ps -eo pid,comm | awk "\$2 ~ /^costume_design/ {print \$1}")
    echo "SIG$signal to the GUI ($gui), its servers running: $(servers)"
    kill -$signal $gui
    n=0
    while [ "$(servers)" -gt 0 ] && [ $n -lt 100 ]; do sleep 0.1; n=$((n + 1)); done
    [ "$(servers)" -eq 0 ] || { echo "FAIL: servers left after SIG$signal"; ps -eo pid,args; exit 1; }
    echo "after SIG$signal: no server left ($((n * 100)) ms)"
    wait
  done
  echo PASS
' "$1"
