#include "process/limited_child.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>

namespace costume::process {
namespace {

// The first byte the child writes says how the work ended; its output follows.
constexpr char kReturnedTag = 'R';
constexpr char kThrewTag = 'E';
constexpr char kOutOfMemoryTag = 'M';

/// The address space this process maps now [bytes] (0 when /proc cannot tell).
std::uint64_t MappedBytes() {
  unsigned long long pages = 0;
  if (FILE* statm = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(statm, "%llu", &pages) != 1) pages = 0;
    std::fclose(statm);
  }
  return pages * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
}

void ApplyLimits(const ChildLimits& limits) {
  // A child stopped at a limit would otherwise dump its gigabytes as a core file.
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  if (limits.memory_bytes > 0) {
    const rlim_t bytes = MappedBytes() + limits.memory_bytes;
    const rlimit memory{bytes, bytes};
    setrlimit(RLIMIT_AS, &memory);
  }
  if (limits.cpu_seconds > 0) {
    // SIGXCPU at the soft limit; the hard limit's SIGKILL if that signal is caught.
    const rlimit cpu{static_cast<rlim_t>(limits.cpu_seconds),
                     static_cast<rlim_t>(limits.cpu_seconds) + 2};
    setrlimit(RLIMIT_CPU, &cpu);
  }
}

bool WriteAll(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t written = write(fd, data, size);
    if (written < 0 && errno == EINTR) continue;
    if (written <= 0) return false;
    data += written;
    size -= static_cast<std::size_t>(written);
  }
  return true;
}

std::string ReadAll(int fd) {
  std::string bytes;
  char buffer[65536];
  for (;;) {
    const ssize_t got = read(fd, buffer, sizeof buffer);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return bytes;
    bytes.append(buffer, static_cast<std::size_t>(got));
  }
}

/// Set in RunLimited's child (each child has its own copy of this process's memory).
bool in_limited_child = false;

[[noreturn]] void RunChild(int fd, const std::function<std::string()>& work,
                           const ChildLimits& limits) {
  in_limited_child = true;
  ApplyLimits(limits);
  char tag = kReturnedTag;
  std::string output;
  try {
    output = work();
  } catch (const std::bad_alloc& error) {
    tag = kOutOfMemoryTag;
    output = error.what();
  } catch (const std::exception& error) {
    output = error.what();
    tag = output.find("bad_alloc") != std::string::npos ? kOutOfMemoryTag : kThrewTag;
  } catch (...) {
    tag = kThrewTag;
    output = "an exception that is not a std::exception";
  }
  const bool sent = WriteAll(fd, &tag, 1) && WriteAll(fd, output.data(), output.size());
  // _exit: no destructors or stdio flushes of state copied from the parent.
  _exit(sent ? 0 : 1);
}

ChildResult Interpret(const std::string& bytes, int status, const rusage& usage,
                      const ChildLimits& limits) {
  ChildResult result;
  if (WIFSIGNALED(status)) {
    result.signal = WTERMSIG(status);
    const bool at_cpu_limit = limits.cpu_seconds > 0 &&
                              usage.ru_utime.tv_sec + usage.ru_stime.tv_sec >= limits.cpu_seconds;
    result.ending = result.signal == SIGXCPU || (result.signal == SIGKILL && at_cpu_limit)
                        ? ChildEnding::kOutOfTime
                        : ChildEnding::kCrashed;
    return result;
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || bytes.empty()) {
    result.ending = ChildEnding::kCrashed;
    return result;
  }
  result.output = bytes.substr(1);
  result.ending = bytes[0] == kReturnedTag      ? ChildEnding::kReturned
                  : bytes[0] == kOutOfMemoryTag ? ChildEnding::kOutOfMemory
                                                : ChildEnding::kThrew;
  return result;
}

}  // namespace

ChildResult RunLimited(const std::function<std::string()>& work, const ChildLimits& limits) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    return {ChildEnding::kNotStarted, std::string("pipe: ") + std::strerror(errno), 0};
  }
  const pid_t pid = fork();
  if (pid < 0) {
    const std::string why = std::string("fork: ") + std::strerror(errno);
    close(fds[0]);
    close(fds[1]);
    return {ChildEnding::kNotStarted, why, 0};
  }
  if (pid == 0) {
    close(fds[0]);
    RunChild(fds[1], work, limits);
  }
  close(fds[1]);
  const std::string bytes = ReadAll(fds[0]);
  close(fds[0]);
  int status = 0;
  rusage usage{};
  while (wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  return Interpret(bytes, status, usage, limits);
}

bool InLimitedChild() { return in_limited_child; }

std::string DescribeEnding(const ChildResult& result, const ChildLimits& limits,
                           const std::string& memory_option, const std::string& time_option) {
  switch (result.ending) {
    case ChildEnding::kReturned:
      return "";
    case ChildEnding::kThrew:
      return result.output;
    case ChildEnding::kOutOfMemory:
      if (limits.memory_bytes == 0) return "ran out of memory (" + result.output + ")";
      return "needed more than " + std::to_string(limits.memory_bytes >> 20) +
             " MB of memory (" + memory_option + ")";
    case ChildEnding::kOutOfTime:
      return "took more than " + std::to_string(limits.cpu_seconds) +
             " s of processor time (" + time_option + ")";
    case ChildEnding::kCrashed: {
      if (result.signal == 0) return "ended without a result";
      const char* name = sigabbrev_np(result.signal);
      return "crashed (signal " + std::to_string(result.signal) +
             (name != nullptr ? std::string(", SIG") + name : std::string()) + ")";
    }
    case ChildEnding::kNotStarted:
      return "could not be run apart: " + result.output;
  }
  return "";
}

}  // namespace costume::process
