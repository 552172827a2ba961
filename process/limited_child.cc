#include "process/limited_child.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
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

/// What the child writes to its standard error, as it comes, its last kKept bytes only: a
/// child that prints without end costs this process no more than that. (Held whole in a file
/// in memory until the child ended, 1 GiB printed took 1 GB of the machine's memory.)
class ErrorTail {
 public:
  static constexpr std::size_t kKept = std::size_t{1} << 16;
  void Append(const char* data, std::size_t size) {
    text_.append(data, size);
    if (text_.size() > 2 * kKept) text_.erase(0, text_.size() - kKept);
  }
  std::string Text() const {
    return text_.size() > kKept ? text_.substr(text_.size() - kKept) : text_;
  }

 private:
  std::string text_;
};

/// Reads the child's result pipe and its standard error (`error_fd`, -1 when it has none of
/// its own) until both end, side by side, so that neither pipe fills and stops the child.
void ReadChild(int result_fd, int error_fd, std::string& result, ErrorTail& errors) {
  pollfd fds[2] = {{result_fd, POLLIN, 0}, {error_fd, POLLIN, 0}};  // poll skips fd -1
  int open = error_fd >= 0 ? 2 : 1;
  char buffer[65536];
  while (open > 0) {
    if (poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      return;
    }
    for (int k = 0; k < 2; ++k) {
      if (fds[k].fd < 0 || fds[k].revents == 0) continue;
      const ssize_t got = read(fds[k].fd, buffer, sizeof buffer);
      if (got < 0 && errno == EINTR) continue;
      if (got <= 0) {
        fds[k].fd = -1;
        --open;
      } else if (k == 0) {
        result.append(buffer, static_cast<std::size_t>(got));
      } else {
        errors.Append(buffer, static_cast<std::size_t>(got));
      }
    }
  }
}

/// The last line of `text` that holds more than blanks, trimmed, its last `most` characters.
std::string LastLine(const std::string& text, std::size_t most) {
  const std::size_t end = text.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "";
  const std::size_t newline = text.rfind('\n', end);
  const std::size_t start = newline == std::string::npos ? 0 : newline + 1;
  const std::size_t length = end + 1 - start;
  return text.substr(start + (length > most ? length - most : 0), std::min(length, most));
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

/// After the child ended: its standard error to this process's when the work returned or
/// threw, else its last line to `result`.
void HandOnErrors(const ErrorTail& errors, ChildResult& result) {
  const std::string text = errors.Text();
  if (result.ending == ChildEnding::kReturned || result.ending == ChildEnding::kThrew) {
    WriteAll(STDERR_FILENO, text.data(), text.size());
  } else {
    result.last_words = LastLine(text, ChildResult::kMaxLastWords);
  }
}

}  // namespace

ChildResult RunLimited(const std::function<std::string()>& work, const ChildLimits& limits) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    return {ChildEnding::kNotStarted, std::string("pipe: ") + std::strerror(errno), 0, ""};
  }
  // Without a pipe for its standard error, the child writes where this process does.
  int error_pipe[2] = {-1, -1};
  if (pipe2(error_pipe, O_CLOEXEC) != 0) error_pipe[0] = error_pipe[1] = -1;
  auto close_all = [&] {
    for (int fd : {fds[0], fds[1], error_pipe[0], error_pipe[1]}) {
      if (fd >= 0) close(fd);
    }
  };
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) {
    const std::string why = std::string("fork: ") + std::strerror(errno);
    close_all();
    return {ChildEnding::kNotStarted, why, 0, ""};
  }
  if (pid == 0) {
    close(fds[0]);
    if (error_pipe[1] >= 0) {
      close(error_pipe[0]);
      dup2(error_pipe[1], STDERR_FILENO);  // the copy is not close-on-exec
    }
    RunChild(fds[1], work, limits);
  }
  close(fds[1]);
  if (error_pipe[1] >= 0) close(error_pipe[1]);
  std::string bytes;
  ErrorTail errors;
  ReadChild(fds[0], error_pipe[0], bytes, errors);
  close(fds[0]);
  if (error_pipe[0] >= 0) close(error_pipe[0]);
  int status = 0;
  rusage usage{};
  while (wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  ChildResult result = Interpret(bytes, status, usage, limits);
  HandOnErrors(errors, result);
  return result;
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
      const std::string said =
          result.last_words.empty() ? "" : "\"" + result.last_words + "\"";
      if (result.signal == 0) return "ended without a result" + (said.empty() ? "" : ": " + said);
      const char* name = sigabbrev_np(result.signal);
      return "crashed (signal " + std::to_string(result.signal) +
             (name != nullptr ? std::string(", SIG") + name : std::string()) +
             (said.empty() ? "" : ": " + said) + ")";
    }
    case ChildEnding::kNotStarted:
      return "could not be run apart: " + result.output;
  }
  return "";
}

}  // namespace costume::process
