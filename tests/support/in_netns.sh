#!/bin/sh
# Runs "$@" in a private network namespace with lo up and a multicast route on it, so LCM's
# UDP multicast stays inside (tests/support/network_namespace.h), with COSTUME_IN_NETNS=1.
# Exit 77 (ctest: skipped) where no namespace can be made (no root, no user namespaces).
unshare -n true 2>/dev/null || { echo "no network namespace: skipped"; exit 77; }
exec unshare -n sh -c '
  ip link set lo up && ip route add 224.0.0.0/4 dev lo || exit 1
  COSTUME_IN_NETNS=1 exec "$@"
' in_netns "$@"
