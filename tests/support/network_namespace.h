#pragma once
/// @file
/// The private network namespace the multi-process tests run in, so that no datagram leaves
/// the machine. ctest starts them through tests/support/in_netns.sh (`unshare -n`, lo up, a
/// multicast route on lo), which sets COSTUME_IN_NETNS; tests/integration/two_hosts.sh sets it
/// for its two namespaces.

#include <cstdlib>

namespace costume::testing {

/// True inside the namespace the test scripts make; a test that sends multicast skips
/// (GTEST_SKIP() << kNeedsNetworkNamespace) otherwise.
inline bool InNetworkNamespace() { return std::getenv("COSTUME_IN_NETNS") != nullptr; }

/// The skip reason outside it.
inline constexpr const char* kNeedsNetworkNamespace =
    "run through ctest: it needs a private network namespace";

}  // namespace costume::testing
