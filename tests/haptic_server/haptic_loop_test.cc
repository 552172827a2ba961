#include "haptic_server/haptic_loop.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <new>
#include <numeric>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "haptic_server/haptic_tick.h"
#include "haptic_server/simulated_device.h"
#include "sim_core/common/input_error.h"

#pragma GCC diagnostic ignored "-Wmismatched-new-delete"  // malloc/free pair below on purpose

// Counts heap allocations while g_counting is set (cf. drake's limit_malloc.h).
namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace costume::haptics {
namespace {

constexpr std::int64_t kPeriod = 1'000'000;  // 1 ms

TEST(PeriodStatistics, NearestRankPercentilesOfOneToAThousand) {
  std::vector<std::int64_t> samples(1000);
  std::iota(samples.begin(), samples.end(), 1);
  std::shuffle(samples.begin(), samples.end(), std::mt19937(7));
  const PeriodStatistics s = ComputePeriodStatistics(samples.data(), 1000, 500);
  EXPECT_EQ(s.num_samples, 1000);
  EXPECT_EQ(s.min, 1);
  EXPECT_EQ(s.p50, 500);
  EXPECT_EQ(s.p99, 990);
  EXPECT_EQ(s.p999, 999);
  EXPECT_EQ(s.max, 1000);
  EXPECT_DOUBLE_EQ(s.mean, 500.5);
  // |p − 500| over 1..1000: 0 once, 1..499 twice, 500 once: the 999th smallest is 499.
  EXPECT_EQ(s.error_max, 500);
  EXPECT_EQ(s.error_p999, 499);
}

class CountingHandler final : public TickHandler {
 public:
  explicit CountingHandler(FakeClock* clock = nullptr) : clock_(clock) {}
  void Tick(const TickInfo& info) override {
    last = info;
    ++ticks;
    if (clock_ != nullptr && info.index == work_at) clock_->Advance(work);
  }
  TickInfo last;
  std::int64_t ticks = 0;
  std::int64_t work_at = -1;
  std::int64_t work = 0;

 private:
  FakeClock* clock_;
};

TEST(HapticLoop, PeriodsAreExactOnAFakeClockWithoutLatency) {
  FakeClock clock(5'000'000);
  CountingHandler handler;
  HapticLoop loop(clock, handler, {kPeriod, 4096, 0});
  loop.Run(1000);
  EXPECT_EQ(handler.ticks, 1000);
  EXPECT_EQ(handler.last.deadline, 5'000'000 + 1000 * kPeriod);
  const PeriodStatistics s = loop.Statistics();
  EXPECT_EQ(s.num_samples, 999);
  EXPECT_EQ(s.min, kPeriod);
  EXPECT_EQ(s.max, kPeriod);
  EXPECT_EQ(s.p999, kPeriod);
  EXPECT_EQ(loop.counters().num_missed, 0);
  EXPECT_EQ(loop.counters().num_overruns, 0);
}

TEST(HapticLoop, AScriptedLateWakeUpShowsInThePeriodStatistics) {
  // Wake-up latencies: 0 everywhere but 300 µs on wake 500 and 40 µs on wakes 100..109.
  // Periods are P + lat_k − lat_(k−1): 1.3 ms and 0.7 ms once each, 1.04 ms and 0.96 ms once
  // each, 1 ms otherwise (1999 periods).
  std::vector<std::int64_t> latency(2000, 0);
  latency[500] = 300'000;
  for (int k = 100; k < 110; ++k) latency[k] = 40'000;
  FakeClock clock;
  clock.ScriptLatencies(latency.data(), 2000);
  CountingHandler handler;
  HapticLoop loop(clock, handler, {kPeriod, 4096, 0});
  loop.Run(2000);
  const PeriodStatistics s = loop.Statistics();
  EXPECT_EQ(s.num_samples, 1999);
  EXPECT_EQ(s.max, 1'300'000);
  EXPECT_EQ(s.min, 700'000);
  EXPECT_EQ(s.p50, kPeriod);
  EXPECT_EQ(s.p99, kPeriod);           // rank 1980 of 1999: still 1 ms
  EXPECT_EQ(s.p999, 1'040'000);        // rank 1998 of 1999: the second largest
  EXPECT_EQ(s.error_max, 300'000);
  EXPECT_EQ(s.error_p999, 300'000);    // errors ascending ..., 0, 40, 40, 300, 300: rank 1998
  EXPECT_EQ(loop.counters().num_missed, 0);
}

TEST(HapticLoop, ALongTickCountsAnOverrunAndSkipsTheMissedDeadline) {
  FakeClock clock;
  CountingHandler handler(&clock);
  handler.work_at = 10;
  handler.work = 2'500'000;  // 2.5 ms of work in tick 10
  HapticLoop loop(clock, handler, {kPeriod, 4096, 0});
  loop.Run(20);
  EXPECT_EQ(loop.counters().num_overruns, 1);
  EXPECT_EQ(loop.counters().num_missed, 1);   // the deadline of tick 11 was skipped
  EXPECT_EQ(handler.ticks, 20);
  // Tick 10 woke at 11 ms; the next wake is at once (13.5 ms > deadline 12 ms, so 12 is
  // skipped and the tick is scheduled for 13 ms), then 14 ms: periods 2.5 ms and 0.5 ms.
  const PeriodStatistics s = loop.Statistics();
  EXPECT_EQ(s.max, 2'500'000);
  EXPECT_EQ(s.min, 500'000);
  EXPECT_EQ(s.num_gaps, 1);  // the 2.5 ms period
  EXPECT_EQ(handler.last.deadline, 21 * kPeriod);  // no lag accumulated: deadlines on the grid
}

// ---- hybrid pacing (Pacer) ---------------------------------------------------------------

constexpr std::int64_t kMargin = 100'000;  // 100 µs
constexpr std::int64_t kReadCost = 50;     // ns per clock read: divides kMargin, so a spin
                                           // from deadline − margin lands on the deadline

TEST(Pacer, AcceptsMarginsFromZeroToHalfThePeriodOnly) {
  FakeClock clock;
  EXPECT_NO_THROW(Pacer(clock, 0, kPeriod));
  EXPECT_NO_THROW(Pacer(clock, kPeriod / 2, kPeriod));
  EXPECT_THROW(Pacer(clock, -1, kPeriod), sim::InputError);
  EXPECT_THROW(Pacer(clock, kPeriod / 2 + 1, kPeriod), sim::InputError);
  try {
    Pacer(clock, kPeriod, kPeriod);
    ADD_FAILURE() << "a margin of a whole period was accepted";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("[0, 500000] ns"), std::string::npos) << error.what();
  }
  EXPECT_THROW(HapticLoop(clock, *std::make_unique<CountingHandler>(), {kPeriod, 16, 0, -5}),
               sim::InputError);
}

// Against an independent model of the fake clock: the sleep wakes at (deadline − margin) +
// latency; the pacer then reads the clock, each read kReadCost later, and returns the first
// reading at or after the deadline.
TEST(Pacer, NeverReturnsBeforeTheDeadlineAndReturnsTheFirstReadingAtOrAfterIt) {
  std::mt19937 random(11);
  std::uniform_int_distribution<std::int64_t> latency_ns(0, 3 * kMargin);
  const int n = 5000;
  std::vector<std::int64_t> latency(n);
  for (std::int64_t& l : latency) l = latency_ns(random);
  latency[7] = kMargin;      // exactly the margin: woke at the deadline, no spin
  latency[8] = kMargin - 1;  // one ns short: one spin read
  FakeClock clock(12'345);
  clock.SetReadCost(kReadCost);
  clock.ScriptLatencies(latency.data(), n);
  Pacer pacer(clock, kMargin, kPeriod);
  std::int64_t expected_exceeded = 0, expected_spin = 0;
  for (int k = 0; k < n; ++k) {
    const std::int64_t deadline = (k + 1) * kPeriod;
    const std::int64_t woke = deadline - kMargin + latency[k];
    std::int64_t expected = woke;
    if (woke >= deadline) {
      ++expected_exceeded;
    } else {
      expected = woke + (deadline - woke + kReadCost - 1) / kReadCost * kReadCost;
      expected_spin += expected - woke;
    }
    const std::int64_t returned = pacer.WaitUntil(deadline);
    ASSERT_GE(returned, deadline) << "wait " << k;
    ASSERT_EQ(returned, expected) << "wait " << k << ", latency " << latency[k];
  }
  EXPECT_EQ(pacer.counters().num_waits, n);
  EXPECT_EQ(pacer.counters().num_margin_exceeded, expected_exceeded);
  EXPECT_EQ(pacer.counters().spin_ns, expected_spin);
  EXPECT_GT(expected_exceeded, 0);        // both branches were taken
  EXPECT_LT(expected_exceeded, n);
}

TEST(Pacer, WithoutAMarginItOnlySleeps) {
  const std::int64_t latency[3] = {0, 70'000, 2'500'000};
  FakeClock clock;
  clock.ScriptLatencies(latency, 3);
  Pacer pacer(clock, 0, kPeriod);
  EXPECT_EQ(pacer.WaitUntil(kPeriod), kPeriod);
  EXPECT_EQ(pacer.WaitUntil(2 * kPeriod), 2 * kPeriod + 70'000);
  EXPECT_EQ(pacer.WaitUntil(3 * kPeriod), 3 * kPeriod + 2'500'000);
  EXPECT_EQ(pacer.counters().num_margin_exceeded, 0);
  EXPECT_EQ(pacer.counters().spin_ns, 0);
}

// The real clock: whatever the machine's wake-up latency, the returned time and a later
// reading are never before the deadline (a property, not a timing threshold).
TEST(Pacer, NeverReturnsEarlyOnTheMonotonicClock) {
  MonotonicClock clock;
  Pacer pacer(clock, 200'000, kPeriod);
  std::int64_t deadline = clock.Now();
  for (int k = 0; k < 200; ++k) {
    deadline += kPeriod;
    const std::int64_t returned = pacer.WaitUntil(deadline);
    ASSERT_GE(returned, deadline);
    ASSERT_GE(clock.Now(), deadline);
  }
  const PacerCounters c = pacer.counters();
  EXPECT_EQ(c.num_waits, 200);
  EXPECT_GE(c.spin_ns, 0);
}

/// Records every tick's deadline and wake time in preallocated storage; optionally works
/// (advances the fake clock) in one tick.
class RecordingHandler final : public TickHandler {
 public:
  RecordingHandler(FakeClock& clock, int capacity) : clock_(clock) {
    deadlines.reserve(capacity);
    wakes.reserve(capacity);
  }
  void Tick(const TickInfo& info) override {
    deadlines.push_back(info.deadline);
    wakes.push_back(info.now);
    if (info.index == work_at) clock_.Advance(work);
  }
  std::vector<std::int64_t> deadlines, wakes;
  std::int64_t work_at = -1;
  std::int64_t work = 0;

 private:
  FakeClock& clock_;
};

TEST(HybridLoop, AnOverrunSkipsGridPointsAndLeavesNoLag) {
  const std::int64_t start = 3'000'123;  // off the millisecond grid on purpose
  FakeClock clock(start);
  clock.SetReadCost(kReadCost);
  RecordingHandler handler(clock, 64);
  handler.work_at = 10;
  handler.work = 3'500'000;  // 3.5 ms of work in tick 10
  HapticLoop loop(clock, handler, {kPeriod, 4096, 0, kMargin});
  loop.Run(30);
  ASSERT_EQ(handler.deadlines.size(), 30u);
  // The first deadline is one period after Run's first reading (`start`). Tick 10 ends 3.5 ms
  // after deadline 10 (plus a few reads): deadlines 11 and 12 are gone, 13 is the next tick's.
  const std::int64_t first = start + kPeriod;
  for (int k = 0; k < 30; ++k) {
    const std::int64_t grid_index = k <= 10 ? k : k + 2;
    EXPECT_EQ(handler.deadlines[k], first + grid_index * kPeriod) << "tick " << k;
    // Woken exactly on the deadline (the spin from deadline − margin lands on it), except the
    // tick after the overrun, which woke as soon as the work ended.
    if (k != 11) {
      EXPECT_EQ(handler.wakes[k], handler.deadlines[k]) << "tick " << k;
    }
  }
  EXPECT_EQ(loop.counters().num_missed, 2);
  EXPECT_EQ(loop.counters().num_overruns, 1);
  EXPECT_EQ(loop.pacer_counters().num_margin_exceeded, 1);
  // Every other wait spun the whole margin.
  EXPECT_EQ(loop.pacer_counters().spin_ns, 29 * kMargin);
}

// Stalls injected as sleep wake-up latencies: a wake s ns after the deadline skips floor(s / P)
// grid points, and those are exactly the ones missing from the ticks' deadlines.
class MissedTicks : public ::testing::TestWithParam<std::int64_t> {};

TEST_P(MissedTicks, EqualTheGridPointsSkippedByInjectedStalls) {
  const std::int64_t margin = GetParam();
  const int n = 2000;
  std::mt19937 random(5);
  std::uniform_int_distribution<int> whole_periods(0, 6);
  // Fractions up to 0.8 P: the next sleep target (0.9 P past the stall's grid point) is still
  // ahead, so every other wait spins the whole margin.
  std::uniform_int_distribution<std::int64_t> fraction(0, kPeriod * 8 / 10);
  std::vector<std::int64_t> latency(n, 0);
  std::vector<std::int64_t> skipped_after(n, 0);  // grid points skipped after tick k − 1
  std::int64_t expected_missed = 0, num_stalls = 0;
  for (int k = 5; k < n; k += 37) {  // stalls far apart
    const std::int64_t late = whole_periods(random) * kPeriod + fraction(random);
    latency[k] = margin + late;  // the sleep aimed `margin` before the deadline
    skipped_after[k] = late / kPeriod;
    expected_missed += late / kPeriod;
    ++num_stalls;
  }
  FakeClock clock;
  clock.SetReadCost(margin > 0 ? kReadCost : 0);
  clock.ScriptLatencies(latency.data(), n);
  RecordingHandler handler(clock, n);
  HapticLoop loop(clock, handler, {kPeriod, 4096, 0, margin});
  loop.Run(n);
  ASSERT_EQ(handler.deadlines.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(loop.counters().num_missed, expected_missed);
  EXPECT_GT(expected_missed, 10);
  for (int k = 1; k < n; ++k) {
    ASSERT_EQ(handler.deadlines[k] - handler.deadlines[k - 1], (1 + skipped_after[k]) * kPeriod)
        << "tick " << k;
  }
  EXPECT_EQ(handler.deadlines.back() - handler.deadlines.front(),
            (n - 1 + expected_missed) * kPeriod);
  EXPECT_EQ(loop.pacer_counters().num_margin_exceeded, margin > 0 ? num_stalls : 0);
  EXPECT_EQ(loop.pacer_counters().spin_ns, margin > 0 ? (n - num_stalls) * margin : 0);
}

INSTANTIATE_TEST_SUITE_P(SleepAndHybrid, MissedTicks, ::testing::Values(0, kMargin),
                         [](const auto& param) { return param.param == 0 ? "Sleep" : "Hybrid"; });

TEST(HybridLoop, StartedAtNormalPriorityItSleepsWithoutSpinning) {
  MonotonicClock clock;
  CountingHandler handler;
  HapticLoop loop(clock, handler, {kPeriod, 4096, /*realtime_priority=*/0, kMargin});
  EXPECT_EQ(loop.spin_margin(), kMargin);  // Run on the caller's thread would spin
  loop.Start();
  while (loop.counters().num_ticks < 20) std::this_thread::yield();
  loop.Stop();
  EXPECT_EQ(loop.spin_margin(), 0);
  EXPECT_EQ(loop.pacer_counters().spin_ns, 0);
  EXPECT_EQ(loop.pacer_counters().num_margin_exceeded, 0);
  EXPECT_NE(loop.realtime_status().reason.find("no spinning at normal priority"),
            std::string::npos)
      << loop.realtime_status().reason;
}

TEST(HybridLoop, AllocatesNothingWhileWaiting) {
  FakeClock clock;
  clock.SetReadCost(kReadCost);
  CountingHandler handler;
  HapticLoop loop(clock, handler, {kPeriod, 4096, 0, kMargin});
  g_allocations = 0;
  g_counting = true;
  loop.Run(1000);
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_EQ(handler.ticks, 1000);
  EXPECT_EQ(loop.pacer_counters().spin_ns, 1000 * kMargin);
}

// A full haptic tick: simulated device, a patch, feedback, safety, the outgoing queue.
TEST(HapticTick, AllocatesNothingWhileTicking) {
  const Trajectory grab = ParseTrajectory("0 0 0 0 1\n2 0.02 0.01 0 1\n", "grab");
  SimulatedDevice device(grab, VirtualHand{}, 1e-3);
  ASSERT_TRUE(device.Open().ok);
  PatchMailbox patches;
  patches.ForEachSlot([](HapticPatch& p) { p.Reserve(64, 256); });
  // A 5×5 lattice, 1 cm spacing, centred on the tip; springs to the right and up.
  HapticPatch& patch = patches.back();
  patch.sequence = 1;
  patch.radius = 0.015;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      patch.positions.emplace_back(0.01 * (i - 2), 0.01 * (j - 2), 0.0);
      patch.velocities.emplace_back(0.0, 0.0, 0.0);
      if (i < 4) patch.springs.push_back({5 * i + j, 5 * (i + 1) + j, 500.0, 0.1, 0.01});
      if (j < 4) patch.springs.push_back({5 * i + j, 5 * i + j + 1, 500.0, 0.1, 0.01});
    }
  }
  PreparePatch(patch);
  ASSERT_GT(patch.num_selected, 1);
  ASSERT_FALSE(patch.boundary_springs.empty());
  patches.Publish();

  OutgoingQueue outgoing;
  FakeClock clock;
  HapticTick tick(device, patches, outgoing, WorkspaceTransform{}, ForceSafetyOptions{});
  HapticLoop loop(clock, tick, {kPeriod, 4096, 0});
  OutgoingDeviceState drained;

  // The counter itself works: one new, one count.
  g_allocations = 0;
  g_counting = true;
  ::operator delete(::operator new(16));  // a direct call, which the compiler may not elide
  g_counting = false;
  ASSERT_EQ(g_allocations.load(), 1);

  g_allocations = 0;
  g_counting = true;
  for (int round = 0; round < 4; ++round) {
    loop.Run(250);
    while (outgoing.TryPop(drained)) {
    }
  }
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_EQ(tick.counters().num_ticks, 1000u);
  EXPECT_EQ(tick.counters().num_patches, 1u);
  EXPECT_EQ(tick.counters().num_dropped_outgoing, 0u);
  // The patch arrived at time 0 and was never refreshed: stale, faded to zero.
  EXPECT_TRUE(tick.safety().flags().stale);
  EXPECT_EQ(tick.last_device_force(), Eigen::Vector3d::Zero());
  EXPECT_GT(tick.safety().counters().num_steps, 0u);
}

TEST(HapticTick, RendersTheFeedbackOfAFreshPatchAndQueuesTheState) {
  const Trajectory hold = ParseTrajectory("0 0 0 0 1\n", "hold");
  SimulatedDevice device(hold, VirtualHand{}, 1e-3);
  ASSERT_TRUE(device.Open().ok);
  PatchMailbox patches;
  OutgoingQueue outgoing;
  FakeClock clock;
  HapticTick tick(device, patches, outgoing, WorkspaceTransform{}, ForceSafetyOptions{});
  HapticLoop loop(clock, tick, {kPeriod, 4096, 0});
  // One selected particle at the tip, tied to an outside one at (0.1, 0, 0) stretched by 1 cm:
  // the cloth pulls the hand with 100 N/m · 0.01 m = 1 N in +x.
  for (int frame = 0; frame < 30; ++frame) {
    HapticPatch& p = patches.back();
    p.sequence = frame + 1;
    p.arrival_time = static_cast<double>(clock.Now()) * 1e-9;
    p.radius = 0.02;
    p.positions = {Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0, 0)};
    p.velocities = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    p.springs = {{0, 1, 100.0, 0.0, 0.09}};
    p.centre = device.hand_position();  // the grab centre the simulation used
    PreparePatch(p);
    patches.Publish();
    loop.Run(16);  // ~60 Hz frames
  }
  // 480 ticks: the ramp (200 ms) is over; the hand has been pulled towards +x by ~1 N / 200 N/m.
  const Eigen::Vector3d f = tick.last_device_force();
  EXPECT_GT(f.x(), 0.9);
  EXPECT_LT(f.x(), 1.0 + 1e-9);
  EXPECT_GT(device.hand_position().x(), 0.003);
  EXPECT_EQ(outgoing.size(), outgoing.capacity());  // nobody drained: the queue filled up
  EXPECT_GT(tick.counters().num_dropped_outgoing, 0u);
  OutgoingDeviceState out;
  ASSERT_TRUE(outgoing.TryPop(out));
  EXPECT_EQ(out.sequence, 0);
  EXPECT_EQ(out.buttons, static_cast<std::uint32_t>(kButtonGrab));
}

}  // namespace
}  // namespace costume::haptics
