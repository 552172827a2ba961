#include "process/child_process.h"

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>

extern char** environ;

namespace costume::process {

pid_t Spawn(const std::vector<std::string>& argv, const SpawnOptions& options,
            std::string* error) {
  if (argv.empty()) {
    if (error != nullptr) *error = "Spawn: no program given";
    return -1;
  }
  std::vector<std::string> copy = argv;  // posix_spawn wants char* const[]
  std::vector<char*> args;
  for (std::string& a : copy) args.push_back(a.data());
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (options.stdout_to_stderr) {
    posix_spawn_file_actions_adddup2(&actions, STDERR_FILENO, STDOUT_FILENO);
  }
  pid_t pid = 0;
  const int failed = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (failed == 0) return pid;
  if (error != nullptr) *error = "posix_spawn " + argv[0] + ": " + std::strerror(failed);
  return -1;
}

int Wait(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

bool Running(pid_t pid) {
  int status = 0;
  return waitpid(pid, &status, WNOHANG) == 0;
}

int Terminate(pid_t pid) {
  if (pid <= 0) return -1;
  kill(pid, SIGTERM);
  return Wait(pid);
}

}  // namespace costume::process
