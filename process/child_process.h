#pragma once
/// @file
/// Child processes: start a program, ask whether it still runs, stop it, collect its exit
/// status. For the programs that drive other processes (tools/haptic_bench) and the
/// multi-process tests (tests/support/child_process.h adds test failures on top).

#include <sys/types.h>

#include <string>
#include <vector>

namespace costume::process {

/// How Spawn starts a child.
struct SpawnOptions {
  /// The child's stdout goes to this process's stderr (when our stdout carries a result,
  /// e.g. a benchmark's JSON).
  bool stdout_to_stderr = false;
};

/// Starts `argv` (argv[0] a path, not searched in PATH) with this process's environment.
/// Returns its pid, or −1 when it could not be started; then `error` (if given) says what
/// failed ("posix_spawn /path/prog: No such file or directory"). Never throws.
pid_t Spawn(const std::vector<std::string>& argv, const SpawnOptions& options = {},
            std::string* error = nullptr);

/// Waits for `pid` to exit; returns its exit status, or −1 when it did not exit normally
/// (killed by a signal) or `pid` is not a child.
int Wait(pid_t pid);

/// True while `pid` has not exited (reaps it when it has).
bool Running(pid_t pid);

/// SIGTERM, then its exit status as Wait. A pid <= 0 (a failed Spawn) returns −1 and signals
/// nothing: kill() would take 0 and −1 as "the whole process group" and "every process".
int Terminate(pid_t pid);

}  // namespace costume::process
