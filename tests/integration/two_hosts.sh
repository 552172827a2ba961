#!/bin/sh
# The workstation split across two hosts of one LAN (issue 5): the haptic server beside the
# device on host B, the simulation on host A. Run by ctest inside `unshare -n` (host A); host B
# is a child network namespace joined to A by a veth pair; both route multicast over the veth
# and the LCM URL's ttl is 1, so datagrams cross the "LAN" and nothing leaves the namespaces.
# Then the grab test runs with the haptic server on B and the simulation and listener on A.
# Usage: two_hosts.sh <grab_release_test binary>
set -eu
test_binary=$1
ip link set lo up
unshare -n sleep 600 </dev/null >/dev/null 2>&1 &
host_b=$!
sleep 0.2
ip link add costume_a type veth peer name costume_b
ip link set costume_b netns "$host_b"
ip addr add 10.77.0.1/24 dev costume_a
ip link set costume_a up
ip route add 224.0.0.0/4 dev costume_a
nsenter -t "$host_b" -n sh -c 'ip link set lo up && ip addr add 10.77.0.2/24 dev costume_b &&
  ip link set costume_b up && ip route add 224.0.0.0/4 dev costume_b'
export COSTUME_IN_NETNS=1
export COSTUME_LCM_URL='udpm://239.255.76.67:7667?ttl=1'
export COSTUME_HAPTIC_NETNS_PID="$host_b"
status=0
"$test_binary" --gtest_filter='GrabRelease.PulledClothFollowsTheDeviceAndReturnsToRestWhenReleased' ||
  status=$?
# Host B's placeholder process holds ctest's output pipe until it is gone.
kill "$host_b"
wait "$host_b" 2>/dev/null || true
exit "$status"
