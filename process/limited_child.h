#pragma once
/// @file
/// Work run in a forked child under memory and processor-time limits, for code this process
/// cannot trust with itself: third-party parsers reading a user's file. assimp 5.2 reading a
/// Collada file whose index list holds "nan" allocates without bound (13 GB within a minute
/// here, then the machine's memory); in a child under a limit the same file costs a second
/// and an error message (docs/catalog.md, "Safety").

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

namespace costume::process {

/// Limits for RunLimited; 0 leaves that resource unlimited.
struct ChildLimits {
  /// Address space the work may map beyond what this process maps when it calls [bytes].
  std::uint64_t memory_bytes = 0;
  /// Processor time the child may use [s].
  int cpu_seconds = 0;
};

/// How the work in the child ended.
enum class ChildEnding {
  kReturned,     ///< it returned; ChildResult::output holds its value
  kThrew,        ///< it threw; output holds the exception's message
  kOutOfMemory,  ///< an allocation failed (std::bad_alloc, caught by the work or not); output
                 ///< holds the message
  kOutOfTime,    ///< stopped at the processor-time limit
  kCrashed,      ///< killed by another signal (ChildResult::signal) or ended without a result
  kNotStarted,   ///< the pipe or the fork failed; output says why
};

/// What RunLimited brings back from the child.
struct ChildResult {
  ChildEnding ending = ChildEnding::kNotStarted;
  std::string output;
  int signal = 0;  ///< the signal that ended the child, 0 when none did
  /// The last line the child wrote to its standard error when it did not return or throw
  /// (a library's assertion, the C library's "munmap_chunk(): invalid pointer"), at most
  /// kMaxLastWords characters; empty when it wrote none.
  std::string last_words;
  static constexpr std::size_t kMaxLastWords = 200;
};

/// Runs `work` in a forked child under `limits` and waits for it. Only `work`'s return value or
/// exception message comes back (through a pipe); whatever else it changes stays in the child. What
/// the child writes to its standard error is held until it ends, its last 64 KB only (a child
/// that prints without end costs no more): written to this process's standard error when the
/// work returned or threw, else kept as ChildResult::last_words (so a dying library's complaint
/// does not land in the middle of the caller's own output). An exception whose
/// message names std::bad_alloc counts as out of memory, as libraries that catch their own
/// exceptions (assimp) report it that way. The child has only the calling thread: `work` must not
/// need locks that other threads of this process may hold (plain parsing and computing is fine;
/// rendering is not). Flush buffered output before calling, or the child's exit may repeat it.
/// Never throws (but std::bad_alloc).
ChildResult RunLimited(const std::function<std::string()>& work, const ChildLimits& limits);

/// True in the child of RunLimited while its work runs. Work that would guard itself with a
/// child of its own runs directly there instead: the limits already hold, and a grandchild
/// stopped at them would report them as its own.
bool InLimitedChild();

/// A phrase for an error message about a child that did not return, naming the limit it hit
/// and `memory_option` / `time_option` (the user's setting for it), e.g. "needed more than
/// 4096 MB of memory (--check-memory-mb)", or the signal it died of and its last words, e.g.
/// "crashed (signal 6, SIGABRT: \"munmap_chunk(): invalid pointer\")". Empty for kReturned.
std::string DescribeEnding(const ChildResult& result, const ChildLimits& limits,
                           const std::string& memory_option, const std::string& time_option);

}  // namespace costume::process
