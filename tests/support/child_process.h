#pragma once
/// @file
/// Child processes for the multi-process tests (label integration): process/child_process.h,
/// with a failed start reported as a test failure naming the program.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "process/child_process.h"

namespace costume::testing {

/// Starts `argv` (argv[0] a path) as a child process with this process's environment;
/// returns its pid (−1 after a test failure naming the program when it could not start).
inline pid_t Spawn(const std::vector<std::string>& argv) {
  std::string error;
  const pid_t pid = process::Spawn(argv, {}, &error);
  EXPECT_GT(pid, 0) << error;
  return pid;
}

/// Waits for `pid`; returns its exit status, or −1 when it did not exit normally.
using process::Wait;
/// True while `pid` has not exited (reaps it when it has).
using process::Running;
/// SIGTERM, then its exit status as Wait (−1 for a pid that never started).
using process::Terminate;

/// Terminates its child when the test leaves early (a failed ASSERT): a server left running
/// holds ctest's output pipe, and ctest then waits for it until the test's timeout.
class TerminatedOnExit {
 public:
  explicit TerminatedOnExit(pid_t pid) : pid_(pid) {}
  TerminatedOnExit(const TerminatedOnExit&) = delete;
  TerminatedOnExit& operator=(const TerminatedOnExit&) = delete;
  ~TerminatedOnExit() {
    if (pid_ > 0 && Running(pid_)) Terminate(pid_);
  }

 private:
  pid_t pid_;
};

}  // namespace costume::testing
