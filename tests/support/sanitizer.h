#pragma once
/// @file
/// Tests of a mechanism AddressSanitizer replaces (scripts/sanitize.sh builds with it).

#include <gtest/gtest.h>

#if defined(__SANITIZE_ADDRESS__)
/// The address-space limit (RLIMIT_AS) of process/limited_child.h cannot hold a process whose
/// sanitizer reserved terabytes of shadow memory before the limit was set: every allocation
/// then fails, and the sanitizer's report of it hung the child. Without the sanitizer the
/// test runs.
#define SKIP_WITH_ADDRESS_SANITIZER_MEMORY_LIMIT()                                       \
  GTEST_SKIP() << "AddressSanitizer's shadow memory leaves no room under an address-space " \
                  "limit"
#else
#define SKIP_WITH_ADDRESS_SANITIZER_MEMORY_LIMIT() static_cast<void>(0)
#endif
