/// @file
/// haptic_bench: the haptic server's timing (issue 5's benchmark, the part without LCM).
///  1. The 1 kHz loop on the real clock for --seconds (default 10; the figure is 60):
///     period p50/p99/p99.9/max, period error, gaps (> 2 periods), missed ticks, overruns, and
///     whether SCHED_FIFO was granted. The tick is the real HapticTick: a simulated device
///     holding a grab, a 1,000-particle patch refreshed at 60 Hz by a separate "I/O" thread
///     (which also drains the outgoing queue), feedback, safety. --load adds a thread spinning
///     on the other core.
///  2. Feedback computation time for lattice patches of 100, 1,000 and 5,000 particles
///     (12 springs per particle, the sphere covering the inner part): PreparePatch (I/O thread,
///     once per frame) and FeedbackForce (every tick).
/// Prints one JSON object on stdout. The haptic → simulation → haptic round trip over LCM is
/// not measured here (no bus in this library).

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "haptic_server/haptic_loop.h"
#include "haptic_server/haptic_tick.h"
#include "haptic_server/simulated_device.h"

namespace {

using namespace costume::haptics;
using nlohmann::json;

/// A rows×cols lattice patch, spacing h, 12 neighbours per particle (structural, shear,
/// bending), centred on the origin, every spring stretched 1 % and particles drifting slowly.
void FillLatticePatch(int rows, int cols, double radius, HapticPatch& patch) {
  const double h = 0.01;
  patch.positions.clear();
  patch.velocities.clear();
  patch.springs.clear();
  patch.radius = radius;
  patch.centre = Eigen::Vector3d::Zero();
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      patch.positions.emplace_back(h * (j - 0.5 * (cols - 1)), 0.001 * std::sin(i + j),
                                   h * (i - 0.5 * (rows - 1)));
      patch.velocities.emplace_back(0.0, 0.01 * std::cos(i * j), 0.0);
    }
  }
  const int offsets[6][2] = {{0, 1}, {1, 0}, {1, 1}, {1, -1}, {0, 2}, {2, 0}};
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      for (const auto& o : offsets) {
        const int i2 = i + o[0], j2 = j + o[1];
        if (i2 >= rows || j2 < 0 || j2 >= cols) continue;
        const int a = i * cols + j, b = i2 * cols + j2;
        const double rest = (patch.positions[b] - patch.positions[a]).norm() / 1.01;
        patch.springs.push_back({a, b, 500.0, 0.05, rest});
      }
    }
  }
}

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::clamp<std::size_t>(rank, 1, v.size()) - 1];
}

json FeedbackTiming(int rows, int cols, int repeats) {
  HapticPatch patch;
  // The sphere covers the inner ~half of the patch (by area); the rest is the margin the
  // simulation sends so boundary springs are complete.
  const double radius = 0.01 * 0.4 * std::min(rows, cols);
  FillLatticePatch(rows, cols, radius, patch);
  using Clock = std::chrono::steady_clock;
  std::vector<double> prepare_us, feedback_us;
  volatile double sink = 0.0;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = Clock::now();
    PreparePatch(patch);
    const auto t1 = Clock::now();
    const Eigen::Vector3d u(1e-4 * (r % 7), 2e-4, -1e-4);
    const Eigen::Vector3d f = FeedbackForce(patch, u);
    const auto t2 = Clock::now();
    sink = sink + f.x();
    prepare_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    feedback_us.push_back(std::chrono::duration<double, std::micro>(t2 - t1).count());
  }
  return {{"particles", rows * cols},
          {"springs", patch.springs.size()},
          {"selected", patch.num_selected},
          {"boundary_springs", patch.boundary_springs.size()},
          {"feedback_us", {{"p50", Percentile(feedback_us, 0.5)},
                           {"p99", Percentile(feedback_us, 0.99)},
                           {"max", Percentile(feedback_us, 1.0)}}},
          {"prepare_us", {{"p50", Percentile(prepare_us, 0.5)},
                          {"p99", Percentile(prepare_us, 0.99)},
                          {"max", Percentile(prepare_us, 1.0)}}}};
}

json LoopTiming(double seconds, bool load, int priority) {
  const Trajectory hold = ParseTrajectory("0 0 0 0 1\n", "hold");
  SimulatedDevice device(hold, VirtualHand{}, 1e-3);
  device.Open();
  PatchMailbox patches;
  patches.ForEachSlot([](HapticPatch& p) { p.Reserve(1000, 6000); });
  OutgoingQueue outgoing;
  MonotonicClock clock;
  HapticTick tick(device, patches, outgoing, WorkspaceTransform{}, ForceSafetyOptions{});
  HapticLoopOptions options;
  options.realtime_priority = priority;
  options.ring_capacity = static_cast<std::int64_t>(seconds * 1000) + 1000;
  HapticLoop loop(clock, tick, options);

  std::atomic<bool> running{true};
  // The I/O thread: a new 1,000-particle patch every 1/60 s, drains the outgoing queue.
  std::thread io([&] {
    std::int64_t next = clock.Now();
    std::uint64_t frame = 0;
    std::uint64_t drained = 0;
    OutgoingDeviceState out;
    while (running.load()) {
      HapticPatch& p = patches.back();
      FillLatticePatch(40, 25, 0.05, p);
      p.sequence = ++frame;
      p.arrival_time = static_cast<double>(clock.Now()) * 1e-9;
      // The grab centre the simulation used; the hand stays within ~1 cm of the origin.
      // (Not device.hand_position(): the tick thread writes that.)
      p.centre = Eigen::Vector3d::Zero();
      PreparePatch(p);
      patches.Publish();
      next += 16'666'667;
      while (clock.Now() < next) {
        while (outgoing.TryPop(out)) ++drained;
        std::this_thread::sleep_for(std::chrono::microseconds(500));
      }
    }
  });
  std::thread spinner;
  if (load) {
    spinner = std::thread([&] {
      volatile double x = 1.0;
      while (running.load(std::memory_order_relaxed)) x = x * 1.0000001 + 1e-9;
    });
  }
  loop.Start();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  loop.Stop();
  running = false;
  io.join();
  if (spinner.joinable()) spinner.join();

  const PeriodStatistics s = loop.Statistics();
  const LoopCounters c = loop.counters();
  const RealtimeStatus rt = loop.realtime_status();
  const auto us = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-3; };
  return {{"seconds", seconds},
          {"load", load},
          {"realtime", rt.realtime},
          {"memory_locked", rt.memory_locked},
          {"realtime_reason", rt.reason},
          {"ticks", c.num_ticks},
          {"missed_ticks", c.num_missed},
          {"overruns", c.num_overruns},
          {"period_us", {{"p50", us(s.p50)}, {"p99", us(s.p99)}, {"p99.9", us(s.p999)},
                         {"max", us(s.max)}, {"min", us(s.min)}, {"mean", s.mean * 1e-3}}},
          {"period_error_us", {{"p99.9", us(s.error_p999)}, {"max", us(s.error_max)}}},
          {"gaps_over_2ms", s.num_gaps},
          {"patches_used", tick.counters().num_patches},
          {"outgoing_dropped", tick.counters().num_dropped_outgoing},
          {"stale_steps", tick.safety().counters().num_stale_steps}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"haptic_bench: 1 kHz loop periods and feedback computation time (JSON)"};
  double seconds = 10.0;
  bool load = false;
  bool skip_loop = false;
  int priority = 80;
  int repeats = 2000;
  app.add_option("--seconds", seconds, "Length of the loop run [s]")->check(CLI::PositiveNumber);
  app.add_flag("--load", load, "Spin a busy thread on the other core during the loop run");
  app.add_option("--priority", priority, "SCHED_FIFO priority to ask for (0: don't)");
  app.add_option("--repeats", repeats, "Feedback timing repetitions per patch size")
      ->check(CLI::PositiveNumber);
  app.add_flag("--skip-loop", skip_loop, "Only time the feedback computation");
  CLI11_PARSE(app, argc, argv);

  json result;
  result["feedback"] = json::array({FeedbackTiming(10, 10, repeats), FeedbackTiming(40, 25, repeats),
                                    FeedbackTiming(100, 50, repeats)});
  if (!skip_loop) result["loop"] = LoopTiming(seconds, load, priority);
  std::cout << result.dump(2) << std::endl;
  return 0;
}
