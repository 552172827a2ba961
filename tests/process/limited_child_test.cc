// Work run in a forked child under limits: each way it can end comes back as that ending,
// and nothing it does reaches this process.

#include "process/limited_child.h"

#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "tests/support/sanitizer.h"

namespace costume::process {
namespace {

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(RunLimited, BringsBackWhatTheWorkReturnsWholeAndLeavesThisProcessUntouched) {
  int touched = 0;
  // 3 MB: many times a pipe's buffer, so the parent must read while the child writes.
  const ChildResult result = RunLimited(
      [&] {
        touched = 1;
        std::string bytes(3 << 20, '\0');
        for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(i * 7 % 251);
        return bytes;
      },
      {});
  ASSERT_EQ(result.ending, ChildEnding::kReturned);
  ASSERT_EQ(result.output.size(), std::size_t{3} << 20);
  for (std::size_t i = 0; i < result.output.size(); i += 4099) {
    ASSERT_EQ(result.output[i], static_cast<char>(i * 7 % 251)) << "byte " << i;
  }
  EXPECT_EQ(touched, 0) << "the child's change reached the parent";
  EXPECT_EQ(result.signal, 0);
}

TEST(RunLimited, TheWorkKnowsItRunsInALimitedChild) {
  EXPECT_FALSE(InLimitedChild());
  const ChildResult result =
      RunLimited([] { return std::string(InLimitedChild() ? "yes" : "no"); }, {});
  ASSERT_EQ(result.ending, ChildEnding::kReturned);
  EXPECT_EQ(result.output, "yes");
  EXPECT_FALSE(InLimitedChild());
}

TEST(RunLimited, AnExceptionComesBackAsItsMessage) {
  const ChildResult result =
      RunLimited([]() -> std::string { throw std::runtime_error("file.dae:3: bad index"); }, {});
  EXPECT_EQ(result.ending, ChildEnding::kThrew);
  EXPECT_EQ(result.output, "file.dae:3: bad index");
  EXPECT_EQ(DescribeEnding(result, {}, "--m", "--t"), "file.dae:3: bad index");
}

TEST(RunLimited, WorkAllocatingBeyondTheMemoryLimitEndsOutOfMemory) {
  SKIP_WITH_ADDRESS_SANITIZER_MEMORY_LIMIT();
  const ChildLimits limits{.memory_bytes = 64ull << 20, .cpu_seconds = 0};
  // Touching 512 MB page by page: fails at the limit, far below what the machine has.
  const ChildResult result = RunLimited(
      [] {
        std::vector<std::vector<char>> blocks;
        for (int i = 0; i < 512; ++i) blocks.emplace_back(1 << 20, 'x');
        return std::to_string(blocks.size());
      },
      limits);
  EXPECT_EQ(result.ending, ChildEnding::kOutOfMemory) << result.output;
  EXPECT_EQ(DescribeEnding(result, limits, "--check-memory-mb", "--t"),
            "needed more than 64 MB of memory (--check-memory-mb)");
}

TEST(RunLimited, AnAllocationFailureALibraryCaughtAndReportedCountsAsOutOfMemory) {
  // assimp catches std::bad_alloc itself and reports its what() as an error string.
  const ChildResult result = RunLimited(
      []() -> std::string {
        throw std::runtime_error("a.dae: cannot read the avatar file: std::bad_alloc");
      },
      {});
  EXPECT_EQ(result.ending, ChildEnding::kOutOfMemory);
}

TEST(RunLimited, WorkThatNeverEndsStopsAtTheProcessorTimeLimit) {
  const ChildLimits limits{.memory_bytes = 0, .cpu_seconds = 1};
  const auto start = std::chrono::steady_clock::now();
  const ChildResult result = RunLimited(
      [] {
        volatile unsigned long spin = 0;
        for (;;) spin = spin + 1;
        return std::string();
      },
      limits);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(result.ending, ChildEnding::kOutOfTime);
  EXPECT_EQ(result.signal, SIGXCPU);
  // 1 s of processor time; more of the wall clock on a loaded machine, never the hard limit's 3.
  EXPECT_GE(seconds, 0.9);
  EXPECT_EQ(DescribeEnding(result, limits, "--m", "--check-seconds"),
            "took more than 1 s of processor time (--check-seconds)");
}

TEST(RunLimited, ACrashIsReportedWithItsSignal) {
  const ChildResult result = RunLimited(
      []() -> std::string {
        std::abort();
      },
      {});
  EXPECT_EQ(result.ending, ChildEnding::kCrashed);
  EXPECT_EQ(result.signal, SIGABRT);
  EXPECT_TRUE(Contains(DescribeEnding(result, {}, "--m", "--t"), "SIGABRT"))
      << DescribeEnding(result, {}, "--m", "--t");
}

// What a dying library writes to standard error (assimp's assertions, the C library's
// "munmap_chunk(): invalid pointer") landed in the middle of the import's progress line;
// it is now the crash's description, and only its last line.
TEST(RunLimited, ACrashsLastWordsAreItsDescriptionNotThisProcesssOutput) {
  const ChildResult result = RunLimited(
      []() -> std::string {
        std::fputs("reading mesh 3\nAssertion `pos < size' failed.\n", stderr);
        std::abort();
      },
      {});
  EXPECT_EQ(result.ending, ChildEnding::kCrashed);
  EXPECT_EQ(result.last_words, "Assertion `pos < size' failed.");
  EXPECT_EQ(DescribeEnding(result, {}, "--m", "--t"),
            "crashed (signal 6, SIGABRT: \"Assertion `pos < size' failed.\")");
  // The C library's own complaint about a damaged heap, as glibc writes it (under
  // AddressSanitizer, the sanitizer's report instead, and an exit without a signal).
  const ChildResult heap = RunLimited(
      []() -> std::string {
        // Not a block malloc gave (16 bytes into one): glibc aborts. Through an integer,
        // so that the compiler does not refuse to build it.
        volatile std::uintptr_t inside = reinterpret_cast<std::uintptr_t>(std::malloc(64)) + 16;
        std::free(reinterpret_cast<void*>(inside));
        return "freed";
      },
      {});
  EXPECT_EQ(heap.ending, ChildEnding::kCrashed);
  EXPECT_FALSE(heap.last_words.empty());
  EXPECT_NE(DescribeEnding(heap, {}, "--m", "--t").find(heap.last_words), std::string::npos);
}

// A child that returns keeps what it wrote to standard error: it reaches this process's.
TEST(RunLimited, WhatAReturningChildWritesToStandardErrorIsPassedOn) {
  ::testing::internal::CaptureStderr();
  const ChildResult result = RunLimited(
      [] {
        std::fputs("a warning\n", stderr);
        return std::string("done");
      },
      {});
  const std::string passed_on = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(result.ending, ChildEnding::kReturned);
  EXPECT_EQ(result.output, "done");
  EXPECT_TRUE(result.last_words.empty());
  EXPECT_EQ(passed_on, "a warning\n");
}

/// The machine's shared memory, files in memory included [kB] (-1 when /proc cannot tell).
long SharedMemoryKb() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  long kb = -1;
  while (meminfo >> key >> kb) {
    if (key == "Shmem:") return kb;
    meminfo.ignore(64, '\n');
  }
  return -1;
}

// 1 GiB written to standard error: this process keeps its last 64 KB, and the machine's
// memory does not hold the rest meanwhile (sampled while the child writes).
TEST(RunLimited, AChildThatPrintsWithoutEndCostsOnlyItsLastWords) {
  if (SharedMemoryKb() < 0) GTEST_SKIP() << "no Shmem in /proc/meminfo";
  constexpr std::size_t kChunk = 1 << 20;
  constexpr int kChunks = 1024;
  std::atomic<bool> running{true};
  std::atomic<long> most_kb{0};
  const long before_kb = SharedMemoryKb();
  std::thread sampler([&] {
    while (running) {
      most_kb = std::max(most_kb.load(), SharedMemoryKb() - before_kb);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  ::testing::internal::CaptureStderr();
  const ChildResult result = RunLimited(
      [] {
        const std::string line(kChunk - 1, 'x');
        for (int k = 0; k < kChunks; ++k) std::fprintf(stderr, "%s\n", line.c_str());
        std::fputs("the end\n", stderr);
        return std::string("done");
      },
      {});
  const std::string passed_on = ::testing::internal::GetCapturedStderr();
  running = false;
  sampler.join();
  EXPECT_EQ(result.ending, ChildEnding::kReturned);
  EXPECT_EQ(result.output, "done");
  EXPECT_EQ(passed_on.size(), std::size_t{1} << 16);
  EXPECT_TRUE(passed_on.ends_with("x\nthe end\n"));
  // Other programs on the machine may change it a little; the child wrote 1,048,576 kB.
  EXPECT_LT(most_kb.load(), 200 * 1024) << "the machine's shared memory grew by that [kB]";
}

TEST(RunLimited, AChildThatExitsWithoutAResultIsNotTakenForSuccess) {
  const ChildResult result = RunLimited(
      []() -> std::string {
        std::_Exit(0);
      },
      {});
  EXPECT_EQ(result.ending, ChildEnding::kCrashed);
  EXPECT_EQ(DescribeEnding(result, {}, "--m", "--t"), "ended without a result");
}

}  // namespace
}  // namespace costume::process
