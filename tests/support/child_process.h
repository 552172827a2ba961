#pragma once
/// @file
/// Child processes for the multi-process tests (label integration): start a program, ask
/// whether it still runs, stop it, collect its exit status.

#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>
#include <vector>

namespace costume::testing {

/// Starts `argv` (argv[0] a path) as a child process with this process's environment;
/// returns its pid. A failed start is a test failure naming the program.
inline pid_t Spawn(std::vector<std::string> argv) {
  std::vector<char*> args;
  for (std::string& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  pid_t pid = 0;
  EXPECT_EQ(posix_spawn(&pid, args[0], nullptr, nullptr, args.data(), environ), 0) << argv[0];
  return pid;
}

/// Waits for `pid`; returns its exit status, or −1 when it did not exit normally.
inline int Wait(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// True while `pid` has not exited (reaps it when it has).
inline bool Running(pid_t pid) {
  int status = 0;
  return waitpid(pid, &status, WNOHANG) == 0;
}

/// SIGTERM, then its exit status as Wait.
inline int Terminate(pid_t pid) {
  kill(pid, SIGTERM);
  return Wait(pid);
}

}  // namespace costume::testing
