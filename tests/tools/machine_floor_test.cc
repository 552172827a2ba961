#include "tools/machine_floor.h"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <thread>
#include <vector>

#include "sim_core/common/monotonic_clock.h"

namespace costume::tools {
namespace {

// A /proc/stat of a 2-CPU guest (Linux 6.x: ten columns after the name).
constexpr const char* kProcStat =
    "cpu  3204181 0 401029 1615494 3187 0 5560 2581 0 0\n"
    "cpu0 1507255 0 195362 908777 773 0 2354 1290 0 0\n"
    "cpu1 1696925 0 205666 706717 2414 0 3205 1291 0 0\n"
    "intr 123456 0 0 0\n"
    "ctxt 987654\n"
    "btime 1700000000\n";

TEST(StealTicks, AreTheEighthColumnOfTheCpuLines) {
  const StealTicks ticks = ParseStealTicks(kProcStat);
  ASSERT_TRUE(ticks.available);
  EXPECT_EQ(ticks.total, 2581);
  EXPECT_EQ(ticks.per_cpu, (std::vector<std::int64_t>{1290, 1291}));
}

TEST(StealTicks, AreUnavailableWithoutAStealColumnOrAFile) {
  EXPECT_FALSE(ParseStealTicks("cpu  1 2 3 4 5 6 7\nintr 5\n").available);
  EXPECT_FALSE(ParseStealTicks("").available);
  EXPECT_FALSE(ReadStealTicks("/nonexistent/stat").available);
}

TEST(StealTicks, DeltasAndSumsArePerCpu) {
  const StealTicks before = ParseStealTicks(kProcStat);
  const StealTicks after = ParseStealTicks(
      "cpu  3204181 0 401029 1615494 3187 0 5560 2600 0 0\n"
      "cpu0 1507255 0 195362 908777 773 0 2354 1294 0 0\n"
      "cpu1 1696925 0 205666 706717 2414 0 3205 1306 0 0\n");
  const StealTicks delta = StealDelta(before, after);
  ASSERT_TRUE(delta.available);
  EXPECT_EQ(delta.total, 19);
  EXPECT_EQ(delta.per_cpu, (std::vector<std::int64_t>{4, 15}));
  const StealTicks twice = StealSum(delta, delta);
  EXPECT_EQ(twice.total, 38);
  EXPECT_EQ(twice.per_cpu, (std::vector<std::int64_t>{8, 30}));
  EXPECT_EQ(StealSum(StealTicks{}, delta).total, 19);
  EXPECT_FALSE(StealDelta(StealTicks{}, after).available);
}

TEST(StealTicks, ParseIntoFixedStorageAgreesWithTheAllocatingParser) {
  std::array<std::int64_t, 4> per_cpu{};
  std::int64_t total = -1;
  EXPECT_EQ(ParseStealInto(kProcStat, per_cpu.data(), 4, &total), 2);
  EXPECT_EQ(total, 2581);
  EXPECT_EQ(per_cpu[0], 1290);
  EXPECT_EQ(per_cpu[1], 1291);
  // CPUs beyond the storage are skipped, lines without a steal column are not counted.
  EXPECT_EQ(ParseStealInto(kProcStat, per_cpu.data(), 1, &total), 1);
  EXPECT_EQ(total, 2581);  // every CPU's line counts in the total, stored or not
  // The total is the CPUs' lines added up, not the aggregate line, which the kernel sums
  // before it prints them: a tick in between shows in a CPU's line only.
  EXPECT_EQ(ParseStealInto("cpu  0 0 0 0 0 0 0 10 0 0\n"
                           "cpu0 0 0 0 0 0 0 0 6 0 0\n"
                           "cpu1 0 0 0 0 0 0 0 5 0 0\n",
                           per_cpu.data(), 4, &total),
            2);
  EXPECT_EQ(total, 11);
  EXPECT_EQ(ParseStealTicks("cpu  0 0 0 0 0 0 0 10 0 0\n"
                            "cpu0 0 0 0 0 0 0 0 6 0 0\n"
                            "cpu1 0 0 0 0 0 0 0 5 0 0\n")
                .total,
            11);
  EXPECT_EQ(ParseStealInto("cpu  1 2 3 4 5 6 7\ncpu0 1 2\n", per_cpu.data(), 4, &total), 0);
}

// A thread that sleeps 5 ms between two samples: one long period, of which it ran only a
// sliver (a sleeping thread accrues neither run time nor run-queue delay while asleep).
TEST(GapWitness, RecordsALongPeriodWithWhatTheThreadDidInIt) {
  constexpr std::int64_t kThreshold = 2'000'000;
  GapWitness witness(kThreshold, 8);
  const std::int64_t start = sim::MonotonicNs();
  witness.Sample(start);
  if (!witness.available()) GTEST_SKIP() << "no /proc/thread-self/schedstat here";
  // A short period, not kept, unless a loaded machine kept this thread off its CPU for
  // longer than the threshold between the two samples: the timestamps say which. The sleep
  // before it has the kernel bring the thread's run time up to date: without it the reading
  // lagged by the test process's start-up, up to a tick, and the long period's count
  // included it (2.5 ms once).
  std::this_thread::sleep_for(std::chrono::microseconds(200));
  const std::int64_t short_end = sim::MonotonicNs();
  witness.Sample(short_end);
  constexpr std::int64_t kSleep = 5'000'000;
  std::this_thread::sleep_for(std::chrono::nanoseconds(kSleep));
  witness.Sample(sim::MonotonicNs());
  // The witness reads the thread's counters inside Sample, after the timestamp it is given,
  // so its counts cover the time between the two reads, which lies within [short_end, end]:
  // on a loaded machine the thread may wait longer between a timestamp and its read than the
  // period lasts, so the counts are bounded by that span, not by the period.
  const std::int64_t end = sim::MonotonicNs();
  const int short_kept = short_end - start > kThreshold ? 1 : 0;
  ASSERT_EQ(witness.num_long(), 1 + short_kept);
  const GapRecord& r = witness.records().at(short_kept);
  EXPECT_GE(r.gap_ns, kSleep);
  EXPECT_GE(r.exec_ns, 0);
  // Asleep for kSleep of it, the thread ran a sliver (the kernel's run-time count of a
  // running thread lags by up to a tick, so no tighter than that).
  EXPECT_LT(r.exec_ns, kSleep / 2);
  EXPECT_GE(r.run_delay_ns, 0);
  EXPECT_LE(r.run_delay_ns, end - short_end);
  EXPECT_GE(r.steal_ticks_cpu, 0);
  EXPECT_GE(r.steal_ticks_all, r.steal_ticks_cpu);
  EXPECT_GE(r.cpu_before, 0);
  // The settled count runs on past the period's end: never less than the period's own.
  std::this_thread::sleep_for(std::chrono::milliseconds(3));
  witness.Break();
  EXPECT_GE(witness.records().at(short_kept).steal_ticks_cpu_settled, r.steal_ticks_cpu);
  EXPECT_GE(witness.records().at(short_kept).steal_ticks_all_settled, r.steal_ticks_all);
}

TEST(GapWitness, KeepsNoPeriodAcrossABreakOrAThreadChange) {
  GapWitness witness(1'000'000, 8);
  witness.Sample(sim::MonotonicNs());
  if (!witness.available()) GTEST_SKIP() << "no /proc/thread-self/schedstat here";
  std::this_thread::sleep_for(std::chrono::milliseconds(3));
  witness.Break();
  witness.Sample(sim::MonotonicNs());
  std::this_thread::sleep_for(std::chrono::milliseconds(3));
  std::thread([&witness] { witness.Sample(sim::MonotonicNs()); }).join();
  EXPECT_EQ(witness.num_long(), 0);
  EXPECT_TRUE(witness.records().empty());
}

TEST(ClockGaps, CountsEachGapOverEveryThresholdBelowIt) {
  ClockGaps gaps;
  for (int i = 0; i < 1000; ++i) gaps.Add(40);  // ordinary reads
  gaps.Add(150'000);                              // > 10, 50, 100 µs
  gaps.Add(2'500'000);                            // > everything up to 2 ms
  gaps.Add(12'000'000);                           // > everything
  gaps.Add(2'000'000);                            // exactly 2 ms: not over it
  EXPECT_EQ(gaps.num_gaps(), 1004);
  EXPECT_EQ(gaps.num_over_threshold(10'000), 4);
  EXPECT_EQ(gaps.num_over_threshold(100'000), 4);
  EXPECT_EQ(gaps.num_over_threshold(500'000), 3);
  EXPECT_EQ(gaps.num_over_threshold(1'000'000), 3);
  EXPECT_EQ(gaps.num_over_threshold(2'000'000), 2);
  EXPECT_EQ(gaps.num_over_threshold(5'000'000), 1);
  EXPECT_EQ(gaps.num_over_threshold(10'000'000), 1);
  EXPECT_EQ(gaps.num_over_threshold(3), -1);
  EXPECT_EQ(gaps.lost_ns(), 150'000 + 2'500'000 + 12'000'000 + 2'000'000);
  EXPECT_EQ(gaps.longest().size(), 10u);
  EXPECT_EQ(gaps.longest()[0], 12'000'000);
  EXPECT_EQ(gaps.longest()[1], 2'500'000);
  EXPECT_EQ(gaps.longest()[2], 2'000'000);
  EXPECT_EQ(gaps.longest()[3], 150'000);
  EXPECT_EQ(gaps.longest()[4], 40);
}

TEST(ClockGaps, MergingEqualsAddingEverythingToOne) {
  const std::vector<std::int64_t> first = {5, 300'000, 7'000'000, 60, 90'000, 11, 3'000'000};
  const std::vector<std::int64_t> second = {8'000'000, 20, 250'000, 1'500'000, 70'000, 9};
  ClockGaps a, b, all;
  for (std::int64_t g : first) a.Add(g), all.Add(g);
  for (std::int64_t g : second) b.Add(g), all.Add(g);
  a.AddSpinTime(100);
  b.AddSpinTime(23);
  a.Merge(b);
  EXPECT_EQ(a.num_gaps(), all.num_gaps());
  EXPECT_EQ(a.spin_ns(), 123);
  for (int i = 0; i < static_cast<int>(ClockGaps::kThresholds.size()); ++i) {
    EXPECT_EQ(a.num_over(i), all.num_over(i)) << ClockGaps::kThresholds[i];
  }
  EXPECT_EQ(a.lost_ns(), all.lost_ns());
  EXPECT_EQ(a.longest(), all.longest());
  EXPECT_EQ(a.longest().front(), 8'000'000);
}

TEST(SpinOnTheClock, SpinsAtLeastTheTimeAskedAndSeesEveryRead) {
  ClockSpinOptions options;
  options.seconds = 0.03;
  options.priority = 0;
  options.burst = 0.01;
  options.rest = 0.001;
  const ClockSpinResult result = SpinOnTheClock(options);
  EXPECT_EQ(result.priority_refusal, "");
  EXPECT_GE(result.gaps.spin_ns(), 30'000'000);
  EXPECT_GT(result.gaps.num_gaps(), 0);
  // The gaps of one burst add up to the burst, so none can exceed the time spun.
  EXPECT_LE(result.gaps.longest().front(), result.gaps.spin_ns());
}

}  // namespace
}  // namespace costume::tools
