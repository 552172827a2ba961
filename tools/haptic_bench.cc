/// @file
/// haptic_bench: the haptic server's timing (issue 5's benchmark). Prints one JSON object.
///  1. Feedback computation time for lattice patches of 100, 1,000 and 5,000 particles
///     (12 springs per particle, the sphere covering the inner part): PreparePatch (I/O thread,
///     once per frame) and FeedbackForce (every tick).
///  2. The 1 kHz loop on the real clock for --seconds each (the figure is 60), in three
///     cases: idle; with the simulation server running (costume_sim_server --builtin garment,
///     playing); with the other core loaded (a child process spinning). Period p50/p99/p99.9/
///     max, period error, gaps > 2 ms, missed ticks, overruns, whether SCHED_FIFO was granted.
///     The tick is the real HapticTick: a simulated device holding a grab, a 1,000-particle
///     patch refreshed at 60 Hz by a separate "I/O" thread, feedback, safety.
///  3. The haptic → simulation → haptic round trip over LCM for --roundtrip-seconds: the bench
///     plays the haptic server's I/O thread, publishing grabs at 250 Hz to a real
///     costume_sim_server (hanging sheet, editing mode) and pressing a new grab every 0.5 s.
///     Transport round trip: a grab's publication to the server's COSTUME_GRAB_ACK for it
///     (sent at once by its receive thread, sim_core/app/grab_acknowledger.h); grab-to-first-patch: a press's publication to the
///     first haptic_patch chunk of that grab (bounded below by the 60 Hz frame).
/// The bench re-executes itself inside `unshare -n` (lo up, multicast routed on it; UDP
/// multicast with ttl=0), as the integration tests do; where no namespace can be made it
/// falls back to memq:// with the simulation server in-process, and says so in "transport".

#include <CLI/CLI.hpp>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "assets/scene_file.h"
#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "haptic_server/haptic_loop.h"
#include "haptic_server/haptic_tick.h"
#include "haptic_server/kernel_preemption.h"
#include "haptic_server/simulated_device.h"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/grab_ack.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"
#include "lcm_types/costume_lcm/status.hpp"
#include "process/child_process.h"
#include "sim_core/app/sim_server.h"
#include "sim_core/common/percentile.h"
#include "tools/machine_floor.h"

namespace {

using namespace costume::haptics;
namespace bus = costume::bus;
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

// ---- the loop and the machine's floor ---------------------------------------------------

std::int64_t ToNs(double seconds) { return static_cast<std::int64_t>(seconds * 1e9); }
double Us(std::int64_t ns) { return static_cast<double>(ns) * 1e-3; }

/// CPU time of this process (all threads) [s].
double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

json StealJson(const costume::tools::StealTicks& steal, double wall_seconds) {
  if (!steal.available) return {{"available", false}};
  const double hz = static_cast<double>(sysconf(_SC_CLK_TCK));
  const double cpus = static_cast<double>(std::max<std::size_t>(1, steal.per_cpu.size()));
  return {{"ticks", steal.total},
          {"per_cpu_ticks", steal.per_cpu},
          {"seconds", static_cast<double>(steal.total) / hz},
          {"fraction_of_cpu_time",
           static_cast<double>(steal.total) / hz / std::max(wall_seconds * cpus, 1e-9)}};
}

/// Forwards to `inner` (none: a tick with no work) and records each tick's wake-up lateness
/// (now − deadline) in storage reserved up front: one store per tick.
class LatencyRecorder final : public TickHandler {
 public:
  /// `witness` (may be null) samples the kernel's accounting at each tick (--attribute-gaps).
  LatencyRecorder(TickHandler* inner, std::int64_t capacity, costume::tools::GapWitness* witness)
      : inner_(inner), witness_(witness) {
    latencies_.reserve(static_cast<std::size_t>(capacity));
  }
  void Tick(const TickInfo& info) override {
    if (latencies_.size() < latencies_.capacity()) latencies_.push_back(info.now - info.deadline);
    if (witness_ != nullptr) witness_->Sample(info.now);
    if (inner_ != nullptr) inner_->Tick(info);
  }
  const std::vector<std::int64_t>& latencies() const { return latencies_; }

 private:
  TickHandler* inner_;
  costume::tools::GapWitness* witness_;
  std::vector<std::int64_t> latencies_;
};

/// The long periods a GapWitness saw, each with what the kernel accounted over it, and their
/// sums: a stall of this kernel shows as run delay, one of the host as steal (and neither).
json GapWitnessJson(const costume::tools::GapWitness& witness) {
  const double tick_ms = 1000.0 / static_cast<double>(sysconf(_SC_CLK_TCK));
  json periods = json::array();
  double gap_ms = 0.0, exec_ms = 0.0, delay_ms = 0.0, steal_cpu_ms = 0.0, steal_all_ms = 0.0;
  for (const costume::tools::GapRecord& r : witness.records()) {
    periods.push_back({{"period_us", Us(r.gap_ns)}, {"exec_us", Us(r.exec_ns)},
                       {"run_delay_us", Us(r.run_delay_ns)},
                       {"steal_ticks_cpu", r.steal_ticks_cpu}, {"steal_ticks_all", r.steal_ticks_all},
                       {"steal_ticks_cpu_settled", r.steal_ticks_cpu_settled},
                       {"steal_ticks_all_settled", r.steal_ticks_all_settled},
                       {"cpu_before", r.cpu_before}, {"cpu_after", r.cpu_after}});
    gap_ms += static_cast<double>(r.gap_ns) * 1e-6;
    exec_ms += static_cast<double>(r.exec_ns) * 1e-6;
    delay_ms += static_cast<double>(r.run_delay_ns) * 1e-6;
    steal_cpu_ms += static_cast<double>(r.steal_ticks_cpu) * tick_ms;
    steal_all_ms += static_cast<double>(r.steal_ticks_all) * tick_ms;
  }
  return {{"available", witness.available()},
          {"long_periods", witness.num_long()},
          {"tick_ms", tick_ms},
          {"periods", periods},
          {"sum_ms", {{"periods", gap_ms}, {"exec", exec_ms}, {"run_delay", delay_ms},
                      {"steal_this_cpu_estimate", steal_cpu_ms},
                      {"steal_all_cpus_estimate", steal_all_ms}}}};
}

/// The real tick's world: a simulated device holding a grab, a 1,000-particle patch refreshed
/// at 60 Hz by an "I/O" thread that also drains the outgoing queue. The I/O thread runs only
/// while the real loop does (StartIo/StopIo), so it is no load on the floor's runs.
class RealTick {
 public:
  RealTick()
      : device_(ParseTrajectory("0 0 0 0 1\n", "hold"), VirtualHand{}, 1e-3),
        tick_(device_, patches_, outgoing_, WorkspaceTransform{}, ForceSafetyOptions{}) {
    device_.Open();
    patches_.ForEachSlot([](HapticPatch& p) { p.Reserve(1000, 6000); });
  }
  ~RealTick() { StopIo(); }
  HapticTick& tick() { return tick_; }

  void StartIo() {
    running_ = true;
    io_ = std::thread([this] {
      std::int64_t next = clock_.Now();
      OutgoingDeviceState out;
      while (running_.load()) {
        HapticPatch& p = patches_.back();
        FillLatticePatch(40, 25, 0.05, p);
        p.sequence = ++frame_;
        p.arrival_time = static_cast<double>(clock_.Now()) * 1e-9;
        // The grab centre the simulation used; the hand stays within ~1 cm of the origin.
        // (Not device.hand_position(): the tick thread writes that.)
        p.centre = Eigen::Vector3d::Zero();
        PreparePatch(p);
        patches_.Publish();
        next += 16'666'667;
        while (running_.load() && clock_.Now() < next) {
          while (outgoing_.TryPop(out)) {
          }
          std::this_thread::sleep_for(std::chrono::microseconds(500));
        }
      }
    });
  }
  void StopIo() {
    running_ = false;
    if (io_.joinable()) io_.join();
  }

 private:
  MonotonicClock clock_;
  SimulatedDevice device_;
  PatchMailbox patches_;
  OutgoingQueue outgoing_;
  HapticTick tick_;
  std::atomic<bool> running_{false};
  std::uint64_t frame_ = 0;
  std::thread io_;
};

/// The real tick's counters, summed over every variant that ran it.
json RealTickCounters(RealTick& real) {
  return {{"patches_used", real.tick().counters().num_patches},
          {"outgoing_dropped", real.tick().counters().num_dropped_outgoing},
          {"stale_steps", real.tick().safety().counters().num_stale_steps}};
}

/// One way of running the 1 kHz loop: the real tick or no work, pure sleep or hybrid pacing.
/// Runs in segments (Segment) so that the variants of a case can take turns.
class LoopVariant {
 public:
  /// `real`: the real tick (null: a bare thread doing no work). `seconds`: the total to come.
  /// `attribute_gaps`: sample the kernel's accounting each tick (GapWitness) for periods > 2 ms.
  LoopVariant(RealTick* real, std::int64_t spin_margin, int priority, double seconds,
              bool attribute_gaps)
      : real_(real),
        spin_margin_(spin_margin),
        witness_(attribute_gaps ? std::make_unique<costume::tools::GapWitness>(2'000'000, 4096)
                                : nullptr),
        recorder_(real != nullptr ? &real->tick() : nullptr, ToNs(seconds) / 1'000'000 + 4096,
                  witness_.get()) {
    HapticLoopOptions options;
    options.realtime_priority = priority;
    options.ring_capacity = static_cast<std::int64_t>(seconds * 1000) + 4096;
    options.spin_margin = spin_margin;
    loop_ = std::make_unique<HapticLoop>(clock_, recorder_, options);
  }

  void Segment(double seconds) {
    const costume::tools::StealTicks steal_before = costume::tools::ReadStealTicks();
    const double cpu_before = ProcessCpuSeconds();
    const std::int64_t start = clock_.Now();
    if (real_ != nullptr) real_->StartIo();
    if (witness_) witness_->Break();  // no period across the pause between segments
    loop_->Start();
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    loop_->Stop();
    if (real_ != nullptr) real_->StopIo();
    wall_ns_ += clock_.Now() - start;
    cpu_seconds_ += ProcessCpuSeconds() - cpu_before;
    steal_ = costume::tools::StealSum(
        steal_, costume::tools::StealDelta(steal_before, costume::tools::ReadStealTicks()));
  }

  json Result() const {
    const PeriodStatistics s = loop_->Statistics();
    const LoopCounters c = loop_->counters();
    const PacerCounters pacing = loop_->pacer_counters();
    const RealtimeStatus rt = loop_->realtime_status();
    const double wall = static_cast<double>(wall_ns_) * 1e-9;
    std::vector<std::int64_t> late = recorder_.latencies();
    std::sort(late.begin(), late.end());
    const auto rank = [&late](double q) {
      return late.empty() ? 0.0 : Us(costume::sim::NearestRankPercentile(
                                       late.data(), static_cast<std::int64_t>(late.size()), q));
    };
    json result = {
        {"seconds", wall},
        {"spin_us", Us(spin_margin_)},
        {"spin_us_in_use", Us(loop_->spin_margin())},
        {"realtime", rt.realtime},
        {"memory_locked", rt.memory_locked},
        {"realtime_reason", rt.reason},
        {"ticks", c.num_ticks},
        {"missed_ticks", c.num_missed},
        {"overruns", c.num_overruns},
        {"period_us", {{"p50", Us(s.p50)}, {"p99", Us(s.p99)}, {"p99.9", Us(s.p999)},
                       {"max", Us(s.max)}, {"min", Us(s.min)}, {"mean", s.mean * 1e-3}}},
        {"period_error_us", {{"p99.9", Us(s.error_p999)}, {"max", Us(s.error_max)}}},
        {"wake_late_us", {{"p50", rank(0.5)}, {"p99", rank(0.99)}, {"p99.9", rank(0.999)},
                          {"max", rank(1.0)}}},
        {"gaps_over_2ms", s.num_gaps},
        {"targets_met", {{"period_error_p99.9_under_100us", s.error_p999 < 100'000},
                         {"no_gap_over_2ms", s.num_gaps == 0}}},
        {"sleeps_woken_past_deadline", pacing.num_margin_exceeded},
        {"spin_fraction_of_a_core", static_cast<double>(pacing.spin_ns) * 1e-9 / std::max(wall, 1e-9)},
        {"process_cpu_fraction_of_a_core", cpu_seconds_ / std::max(wall, 1e-9)},
        {"steal", StealJson(steal_, wall)}};
    if (witness_) result["gap_witness"] = GapWitnessJson(*witness_);
    return result;
  }

 private:
  MonotonicClock clock_;
  RealTick* real_;
  std::int64_t spin_margin_;
  std::unique_ptr<costume::tools::GapWitness> witness_;
  LatencyRecorder recorder_;
  std::unique_ptr<HapticLoop> loop_;
  std::int64_t wall_ns_ = 0;
  double cpu_seconds_ = 0.0;
  costume::tools::StealTicks steal_;
};

/// The spinning thread of the floor, in segments like the loop variants.
class ClockSpinVariant {
 public:
  /// `attribute_gaps`: the spinner samples a GapWitness every 100 µs of spinning.
  ClockSpinVariant(int priority, bool attribute_gaps)
      : priority_(priority),
        witness_(attribute_gaps ? std::make_unique<costume::tools::GapWitness>(2'000'000, 4096)
                                : nullptr) {}

  void Segment(double seconds) {
    const costume::tools::StealTicks steal_before = costume::tools::ReadStealTicks();
    const auto start = std::chrono::steady_clock::now();
    costume::tools::ClockSpinOptions options;
    options.seconds = seconds * options.burst / (options.burst + options.rest);
    options.priority = priority_;
    options.witness = witness_.get();
    const costume::tools::ClockSpinResult run = costume::tools::SpinOnTheClock(options);
    gaps_.Merge(run.gaps);
    if (!run.priority_refusal.empty()) refusal_ = run.priority_refusal;
    wall_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    steal_ = costume::tools::StealSum(
        steal_, costume::tools::StealDelta(steal_before, costume::tools::ReadStealTicks()));
  }

  const costume::tools::ClockGaps& gaps() const { return gaps_; }
  double spin_seconds() const { return static_cast<double>(gaps_.spin_ns()) * 1e-9; }
  const costume::tools::StealTicks& steal() const { return steal_; }

  json Result() const {
    json over = json::array();  // [threshold µs, count] in ascending order
    for (std::size_t i = 0; i < costume::tools::ClockGaps::kThresholds.size(); ++i) {
      over.push_back({Us(costume::tools::ClockGaps::kThresholds[i]),
                      gaps_.num_over(static_cast<int>(i))});
    }
    std::vector<double> longest;
    for (std::int64_t g : gaps_.longest()) longest.push_back(Us(g));
    const double spun = std::max(spin_seconds(), 1e-9);
    json result = {{"seconds_spinning", spin_seconds()},
            {"seconds_wall", wall_seconds_},
            {"fifo_priority", priority_},
            {"fifo_refused", refusal_},
            {"reads", gaps_.num_gaps()},
            {"mean_read_ns", 1e9 * spun / std::max<double>(1.0, static_cast<double>(gaps_.num_gaps()))},
            {"longest_gaps_us", longest},
            {"gaps_over_us_count", over},
            {"gaps_over_100us", gaps_.num_over_threshold(100'000)},
            {"gaps_over_2ms", gaps_.num_over_threshold(2'000'000)},
            {"gaps_over_2ms_per_60s", 60.0 * static_cast<double>(gaps_.num_over_threshold(2'000'000)) / spun},
            {"seconds_lost_in_gaps_over_100us", static_cast<double>(gaps_.lost_ns()) * 1e-9},
            {"steal", StealJson(steal_, wall_seconds_)}};
    if (witness_) result["gap_witness"] = GapWitnessJson(*witness_);
    return result;
  }

 private:
  int priority_;
  std::unique_ptr<costume::tools::GapWitness> witness_;
  costume::tools::ClockGaps gaps_;
  std::string refusal_;
  double wall_seconds_ = 0.0;
  costume::tools::StealTicks steal_;
};

/// printf into a std::string (for the conclusions' sentences).
template <typename... Args>
std::string Format(const char* format, Args... args) {
  std::string text(1024, '\0');
  const int n = std::snprintf(text.data(), text.size(), format, args...);
  text.resize(static_cast<std::size_t>(std::clamp(n, 0, static_cast<int>(text.size()) - 1)));
  return text;
}

/// Where the long periods of the loop variants went (--attribute-gaps), summed over variants:
/// the time beyond the nominal period, how much of it this kernel made the thread wait on a
/// run queue, and the steal /proc/stat counted from each period's start to 20 ms after its
/// end (the guest books steal at its next scheduler tick). Steal comes in 10 ms ticks, so per
/// period the count is 0 or 1 with mean stolen/10 ms: its sum estimates the stolen time, with
/// the binomial spread shown, were all the time neither running nor queued stolen.
json GapAttribution(const json& variants, double nominal_ms) {
  double excess_ms = 0.0, delay_ms = 0.0, steal_ms = 0.0, settled_ms = 0.0, tick_ms = 10.0;
  double variance = 0.0;  // of the settled steal count, were the unqueued time all stolen
  std::int64_t periods = 0;
  for (const auto& [name, v] : variants.items()) {
    if (!v.is_object() || !v.contains("gap_witness")) continue;
    const json& w = v["gap_witness"];
    tick_ms = w.value("tick_ms", 10.0);
    for (const json& p : w["periods"]) {
      const double excess = p["period_us"].get<double>() * 1e-3 - nominal_ms;
      const double delay = p["run_delay_us"].get<double>() * 1e-3;
      const double q = std::clamp((excess - delay) / tick_ms, 0.0, 1.0);
      excess_ms += excess;
      delay_ms += delay;
      steal_ms += static_cast<double>(p["steal_ticks_cpu"].get<std::int64_t>()) * tick_ms;
      settled_ms += static_cast<double>(p["steal_ticks_cpu_settled"].get<std::int64_t>()) * tick_ms;
      variance += q * (1.0 - q) * tick_ms * tick_ms;
      ++periods;
    }
  }
  const double unqueued_ms = excess_ms - delay_ms;
  json a = {{"periods_over_2ms", periods},
            {"ms_beyond_nominal", excess_ms},
            {"run_queue_delay_ms", delay_ms},
            {"neither_running_nor_queued_ms", unqueued_ms},
            {"steal_counted_ms", steal_ms},
            {"steal_counted_settled_ms", settled_ms},
            {"steal_spread_ms", std::sqrt(variance)}};
  if (periods == 0) {
    a["conclusion"] = "No loop period over 2 ms to attribute.";
    return a;
  }
  a["conclusion"] = Format(
      "%lld periods over 2 ms, %.1f ms beyond the nominal period in all. %.1f ms (%.0f %%) the "
      "woken threads waited on a run queue of this kernel (a kernel path that does not yield, "
      "or a higher-priority thread). %.1f ms (%.0f %%) passed with them neither running nor "
      "queued: the wake-up itself came late, no guest thread could have run then. Steal "
      "counted for their CPU from each period's start to 20 ms after its end: %.0f ms (%.0f +- "
      "%.0f ms were all of the unqueued time stolen by the host).",
      static_cast<long long>(periods), excess_ms, delay_ms,
      100.0 * delay_ms / std::max(excess_ms, 1e-9), unqueued_ms,
      100.0 * unqueued_ms / std::max(excess_ms, 1e-9), settled_ms, unqueued_ms, std::sqrt(variance));
  return a;
}

/// The 'no gap over 2 ms' target against the floor: the thread that never sleeps (the clock
/// spinner) against the bare threads that sleep between ticks and do nothing else.
std::string GapConclusion(const json& variants, const ClockSpinVariant& spin, json& floor) {
  const std::int64_t spin_gaps = spin.gaps().num_over_threshold(2'000'000);
  const double longest = spin.gaps().longest().empty() ? 0.0 : Us(spin.gaps().longest()[0]);
  const double steal_s = StealJson(spin.steal(), 1.0).value("seconds", 0.0);
  const double lost_s = static_cast<double>(spin.gaps().lost_ns()) * 1e-9;
  std::int64_t bare_gaps = 0;
  double bare_max = 0.0, bare_seconds = 0.0;
  for (const char* name : {"bare_sleep", "bare_hybrid"}) {
    bare_gaps += variants[name]["gaps_over_2ms"].get<std::int64_t>();
    bare_max = std::max(bare_max, variants[name]["period_us"]["max"].get<double>());
    bare_seconds += variants[name]["seconds"].get<double>();
  }
  // Had the spinner lost the CPU as often as the bare threads saw long gaps (Poisson, the bare
  // threads' rate), the chance it would still have seen none: a short run proves little.
  const double none_by_chance =
      std::exp(-static_cast<double>(bare_gaps) / std::max(bare_seconds, 1e-9) * spin.spin_seconds());
  floor["clock_spin_gaps_over_2ms"] = spin_gaps;
  floor["clock_spin_longest_gap_us"] = longest;
  floor["clock_spin_seconds"] = spin.spin_seconds();
  floor["steal_seconds_while_spinning"] = steal_s;
  floor["bare_threads_gaps_over_2ms"] = bare_gaps;
  floor["bare_threads_seconds"] = bare_seconds;
  floor["clock_spin_no_gap_by_chance_probability"] = none_by_chance;
  floor["no_gap_over_2ms_possible_here"] = spin_gaps == 0;
  floor["no_gap_over_2ms_possible_for_a_thread_that_sleeps"] = spin_gaps == 0 && bare_gaps == 0;
  if (spin_gaps > 0) {
    return Format(
        "A thread with nothing to do but read CLOCK_MONOTONIC lost the CPU for more than 2 ms "
        "%lld times in %.1f s of spinning (longest %.0f us; %.3f s lost in its gaps over 100 us, "
        "while the CPUs' steal time grew by %.2f s). No thread on that CPU runs during such a "
        "gap, so no pacing or loop code can meet 'no gap over 2 ms in 60 s' on this machine in "
        "this case.",
        static_cast<long long>(spin_gaps), spin.spin_seconds(), longest, lost_s, steal_s);
  }
  if (bare_gaps > 0 && none_by_chance >= 0.05) {
    return Format(
        "A thread spinning on CLOCK_MONOTONIC saw no gap over 2 ms in %.1f s (longest %.0f us), "
        "the bare sleeping threads %lld in %.1f s (longest %.0f us); at their rate the spinner "
        "would have seen none with probability %.2f anyway: too short a run to tell whether the "
        "long gaps come with sleeping or with the machine (try --seconds 60).",
        spin.spin_seconds(), longest, static_cast<long long>(bare_gaps), bare_seconds, bare_max,
        none_by_chance);
  }
  if (bare_gaps > 0) {
    return Format(
        "A thread that never sleeps, reading CLOCK_MONOTONIC, saw no gap over 2 ms in %.1f s "
        "(longest %.0f us), but the bare threads, which sleep between ticks and do no work, had "
        "%lld periods over 2 ms (longest %.0f us): here the long gaps come with waking from "
        "sleep, not with running: they are no fault of the tick's work, and by the spinner's figure "
        "only a loop that never slept (a whole core) would avoid them on this machine (chance "
        "of the spinner seeing none at the bare threads' rate: %.3f).",
        spin.spin_seconds(), longest, static_cast<long long>(bare_gaps), bare_max, none_by_chance);
  }
  return Format(
      "Neither the thread spinning on CLOCK_MONOTONIC (%.1f s, longest gap %.0f us) nor the bare "
      "sleeping threads saw a gap over 2 ms: the machine allowed the 'no gap' target in this "
      "case; gaps of the real loop come from its work or the I/O beside it.",
      spin.spin_seconds(), longest);
}

/// The 'p99.9 period error under 100 µs' target: the bare thread against the real loop.
std::string ErrorConclusion(const json& variants, json& floor) {
  const auto error = [&variants](const char* name) {
    return variants[name]["period_error_us"]["p99.9"].get<double>();
  };
  const double bare_sleep = error("bare_sleep"), bare_hybrid = error("bare_hybrid");
  const double best_bare = std::min(bare_sleep, bare_hybrid);
  floor["bare_thread_period_error_p99.9_us"] = best_bare;
  floor["period_error_p99.9_under_100us_reached_by_a_bare_thread"] = best_bare < 100.0;
  return Format(
      "p99.9 period error: a bare SCHED_FIFO thread doing no work %.1f us sleeping, %.1f us with "
      "the hybrid pacer; the real loop %.1f us and %.1f us. %s",
      bare_sleep, bare_hybrid, error("real_sleep"), error("real_hybrid"),
      best_bare < 100.0 ? "The machine allows < 100 us here; a larger real figure is the loop's."
                        : "Even with no work neither pacer got under 100 us: that floor is the "
                          "machine's, not the loop's.");
}

/// What the floor's data say about the two loop targets, in words and flags.
json FloorConclusion(const json& variants, const ClockSpinVariant& spin) {
  json floor;
  const std::string gaps = GapConclusion(variants, spin, floor);
  const std::string error = ErrorConclusion(variants, floor);
  floor["conclusion"] = {gaps, error};
  return floor;
}

/// The spinning thread's long periods between witness samples (every 100 µs of spinning): a
/// thread that never sleeps is either running, queued, or stopped where this kernel cannot
/// see it. Run time close to the period means the kernel believed it ran all along: only
/// the host (or firmware) can have taken that time.
json SpinAttribution(const json& spin) {
  if (!spin.contains("gap_witness")) return json::object();
  double period_ms = 0.0, exec_ms = 0.0, delay_ms = 0.0;
  std::int64_t periods = 0;
  for (const json& p : spin["gap_witness"]["periods"]) {
    period_ms += p["period_us"].get<double>() * 1e-3;
    exec_ms += p["exec_us"].get<double>() * 1e-3;
    delay_ms += p["run_delay_us"].get<double>() * 1e-3;
    ++periods;
  }
  json a = {{"periods_over_2ms", periods}, {"period_ms", period_ms}, {"exec_ms", exec_ms},
            {"run_queue_delay_ms", delay_ms}};
  a["conclusion"] =
      periods == 0
          ? std::string("The spinning thread had no period over 2 ms between its samples.")
          : Format("The spinning thread had %lld periods over 2 ms between its 100 us samples, "
                   "%.1f ms in all; this kernel counted %.1f ms of them as its run time (%.0f "
                   "%%) and %.2f ms as waiting on a run queue: where run time covers the period, "
                   "the kernel believed the thread was running while it was not, i.e. the "
                   "virtual CPU was stopped by the host.",
                   static_cast<long long>(periods), period_ms, exec_ms,
                   100.0 * exec_ms / std::max(period_ms, 1e-9), delay_ms);
  return a;
}

/// One case of the loop part: the real loop with both pacers and the floor (a bare thread
/// with both pacers, a thread spinning on the clock), taking turns in rounds of about
/// `round_seconds` so that a burst of load falls on all of them alike; each gets `seconds`.
struct LoopCaseOptions {
  double seconds = 10.0;
  double round_seconds = 5.0;
  int priority = 80;
  std::int64_t spin_margin = kDefaultSpinMargin;
  bool with_floor = true;
  bool attribute_gaps = false;
};

json LoopCase(const LoopCaseOptions& o) {
  const auto variant = [&o](RealTick* real, std::int64_t margin) {
    return std::make_unique<LoopVariant>(real, margin, o.priority, o.seconds, o.attribute_gaps);
  };
  RealTick real;
  std::map<std::string, std::unique_ptr<LoopVariant>> loops;
  loops["real_sleep"] = variant(&real, 0);
  loops["real_hybrid"] = variant(&real, o.spin_margin);
  std::unique_ptr<ClockSpinVariant> spin;
  if (o.with_floor) {
    loops["bare_sleep"] = variant(nullptr, 0);
    loops["bare_hybrid"] = variant(nullptr, o.spin_margin);
    spin = std::make_unique<ClockSpinVariant>(o.priority, o.attribute_gaps);
  }
  std::vector<std::function<void(double)>> turns;
  for (auto& [name, loop] : loops) turns.push_back([&loop](double s) { loop->Segment(s); });
  if (spin) turns.push_back([&spin](double s) { spin->Segment(s); });

  const int rounds = std::max(1, static_cast<int>(std::lround(o.seconds / o.round_seconds)));
  const double segment = o.seconds / rounds;
  const costume::tools::StealTicks steal_before = costume::tools::ReadStealTicks();
  const auto start = std::chrono::steady_clock::now();
  for (int r = 0; r < rounds; ++r) {
    for (std::size_t i = 0; i < turns.size(); ++i) turns[(r + i) % turns.size()](segment);
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  json result;
  result["rounds"] = rounds;
  result["seconds_each"] = o.seconds;
  result["spin_us"] = Us(o.spin_margin);
  result["steal_over_the_case"] = StealJson(
      costume::tools::StealDelta(steal_before, costume::tools::ReadStealTicks()), wall);
  json side_by_side;
  for (const auto& [name, loop] : loops) {
    result[name] = loop->Result();
    const json& v = result[name];
    side_by_side[name] = {{"period_error_p99.9_us", v["period_error_us"]["p99.9"]},
                          {"period_max_us", v["period_us"]["max"]},
                          {"gaps_over_2ms", v["gaps_over_2ms"]},
                          {"missed_ticks", v["missed_ticks"]},
                          {"process_cpu_fraction", v["process_cpu_fraction_of_a_core"]},
                          {"steal_seconds", v["steal"].value("seconds", 0.0)}};
  }
  if (spin) {
    result["clock_spin"] = spin->Result();
    side_by_side["clock_spin"] = {
        {"gaps_over_100us", result["clock_spin"]["gaps_over_100us"]},
        {"gaps_over_2ms", result["clock_spin"]["gaps_over_2ms"]},
        {"longest_gap_us", spin->gaps().longest().empty() ? 0.0 : Us(spin->gaps().longest()[0])},
        {"steal_seconds", result["clock_spin"]["steal"].value("seconds", 0.0)}};
  }
  result["side_by_side"] = side_by_side;
  if (o.attribute_gaps) result["gap_attribution"] = GapAttribution(result, 1.0);
  if (o.attribute_gaps && spin) result["clock_spin_attribution"] = SpinAttribution(result["clock_spin"]);
  result["real_tick_both_pacers"] = RealTickCounters(real);
  if (spin) result["machine_floor"] = FloorConclusion(result, *spin);
  return result;
}

// ---- processes ---------------------------------------------------------------------------

/// A program's child process whose output goes to our stderr (stdout is the JSON); −1 with a
/// message on stderr when it cannot start.
pid_t Spawn(const std::vector<std::string>& argv) {
  std::string error;
  costume::process::SpawnOptions options;
  options.stdout_to_stderr = true;
  const pid_t pid = costume::process::Spawn(argv, options, &error);
  if (pid < 0) std::cerr << "haptic_bench: " << error << "\n";
  return pid;
}

using costume::process::Terminate;

/// A child process spinning on the other core until killed.
pid_t StartBusyChild() {
  const pid_t pid = fork();
  if (pid == 0) {
    volatile double x = 1.0;
    for (;;) x = x * 1.0000001 + 1e-9;
  }
  return pid;
}

/// The hanging sheet of the integration tests (33 × 33, z = −0.5, pinned top corners).
std::string HangingSheet() {
  return "name = \"hanging\"\nduration = 600.0\n"
         "[solver]\nmethod = \"pcg\"\ntolerance = 1e-3\nstrain_limit = 0.0\n"
         "[[material]]\nname = \"cloth\"\nbase = \"stiff_cotton\"\n"
         "[[garment]]\nname = \"sheet\"\nmaterial = \"cloth\"\n"
         "pin_points = [[-0.5, 0, -0.5], [0.5, 0, -0.5]]\n"
         "[garment.panel]\norigin = [-0.5, 0, -0.5]\nu_axis = [1, 0, 0]\n"
         "v_axis = [0, -1, 0]\nsize = [1.0, 1.0]\nresolution = [33, 33]\n";
}

std::int64_t SteadyNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

json Summary(std::vector<double> v, const char* unit) {
  if (v.empty()) return {{"samples", 0}};
  return {{"samples", v.size()}, {"unit", unit}, {"p50", Percentile(v, 0.5)},
          {"p99", Percentile(v, 0.99)}, {"max", Percentile(v, 1.0)}};
}

// ---- the round trip ----------------------------------------------------------------------

/// The haptic side of the round trip on `bus`: grabs at 250 Hz at the sheet's middle, a new
/// press every 0.5 s (held 0.25 s), for `seconds`. `pump` runs whatever must run between
/// publications (the bus's own handling, and with memq the in-process server's frames) until
/// the given steady-clock time [ns].
json RoundTrip(bus::MessageBus& bus, double seconds,
               const std::function<void(std::int64_t)>& pump) {
  std::map<std::int64_t, std::int64_t> sent;        // grab seq → publication time [ns]
  std::map<std::int64_t, std::int64_t> pressed;     // grab id → press publication time [ns]
  std::map<std::int64_t, std::int64_t> first_patch; // grab id → first patch chunk [ns]
  std::vector<double> transport_us;
  bus::ReceivePolicy any;
  any.max_age_us = any.max_lead_us = 0;
  bus::Subscribe<costume_lcm::grab_ack>(
      bus, bus::kGrabAckChannel,
      [&](const costume_lcm::grab_ack& ack) {
        const std::int64_t now = SteadyNs();
        const auto found = sent.find(ack.grab_seq);
        if (found != sent.end()) transport_us.push_back(1e-3 * static_cast<double>(now - found->second));
      },
      any);
  bus::Subscribe<costume_lcm::haptic_patch>(
      bus, bus::kHapticPatchChannel,
      [&](const costume_lcm::haptic_patch& chunk) {
        if (!first_patch.count(chunk.grab_id)) first_patch[chunk.grab_id] = SteadyNs();
      },
      any);
  bus::Publisher<costume_lcm::grab> publisher(bus, bus::kGrabChannel);
  costume_lcm::grab grab{};
  grab.radius = 0.05;
  grab.gaussian_sigma = 0.025;
  grab.coupling_stiffness = 200.0;
  grab.centre[1] = -0.5;
  grab.centre[2] = -0.5;
  const std::int64_t start = SteadyNs();
  const std::int64_t period = 4'000'000;  // 250 Hz, as the haptic server publishes
  std::int64_t grab_id = -1;
  for (std::int64_t k = 0; SteadyNs() - start < static_cast<std::int64_t>(seconds * 1e9); ++k) {
    const std::int64_t t = start + k * period;
    const bool press = (k % 125) < 63;  // 0.5 s cycle, ~0.25 s held
    if (press && k % 125 == 0) ++grab_id;
    grab.mode = press ? costume_lcm::grab::MODE_GRAB : costume_lcm::grab::MODE_HOVER;
    grab.buttons = press ? 1 : 0;
    grab.grab_id = std::max<std::int64_t>(grab_id, 0);
    grab.utime = bus::NowUtime();
    const std::int64_t now = SteadyNs();
    sent[publisher.next_seq()] = now;
    if (press && k % 125 == 0) pressed[grab_id] = now;
    publisher.Publish(grab);
    pump(t + period);
  }
  pump(SteadyNs() + 200'000'000);  // the last answers
  std::vector<double> to_patch_ms;
  for (const auto& [id, t] : pressed) {
    const auto found = first_patch.find(id);
    if (found != first_patch.end()) to_patch_ms.push_back(1e-6 * static_cast<double>(found->second - t));
  }
  const json transport = Summary(transport_us, "us");
  json result = {{"seconds", seconds},
                 {"grabs_sent", sent.size()},
                 {"acks_received", transport_us.size()},
                 {"presses", pressed.size()},
                 {"presses_answered_by_a_patch", to_patch_ms.size()},
                 {"transport_round_trip", transport},
                 {"grab_to_first_patch", Summary(to_patch_ms, "ms")}};
  if (!transport_us.empty()) {
    result["targets_met"] = {{"round_trip_p99_under_1ms", Percentile(transport_us, 0.99) < 1000.0}};
  }
  return result;
}

/// Over UDP multicast to a costume_sim_server process (inside the namespace).
/// Back to normal scheduling for the calling thread (after a TryThreadFifoPriority).
void NormalPriority() {
  sched_param param{};
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &param);
}

/// `io_priority`: the SCHED_FIFO priority this thread asks for while it plays the haptic
/// server's I/O thread (asked after the server is spawned, so the server does not inherit it:
/// its acknowledger asks for its own, --ack-priority).
json RoundTripOverUdp(const std::string& sim_server, double seconds, int io_priority,
                      int ack_priority) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("haptic_bench_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.toml") << HangingSheet();
  bus::LcmBus bus("udpm://239.255.76.67:7667?ttl=0");
  bool up = false;
  std::string ack_refusal;
  bus::Subscribe<costume_lcm::status>(bus, bus::kSimStatusChannel,
                                      [&](const costume_lcm::status& status) {
                                        up = true;
                                        for (const std::string& w : status.warnings) {
                                          if (w.find("grab acknowledger") != std::string::npos) {
                                            ack_refusal = w;
                                          }
                                        }
                                      });
  const pid_t sim = Spawn({sim_server, "--scene", (dir / "scene.toml").string(), "--editing",
                           "--lcm-url", "udpm://239.255.76.67:7667?ttl=0", "--ack-priority",
                           std::to_string(ack_priority)});
  const std::int64_t give_up = SteadyNs() + 10'000'000'000;
  while (!up && SteadyNs() < give_up) bus.HandleSubscriptions(50);
  json result;
  if (!up) {
    result = {{"error", "the simulation server did not come up: " + sim_server}};
  } else {
    const std::string io_refusal =
        io_priority > 0 ? TryThreadFifoPriority(io_priority) : "not asked";
    result = RoundTrip(bus, seconds, [&bus](std::int64_t until) {
      for (std::int64_t now = SteadyNs(); now < until; now = SteadyNs()) {
        bus.HandleSubscriptions(static_cast<int>(std::max<std::int64_t>(1, (until - now) / 1'000'000)));
      }
    });
    NormalPriority();
    result["io_thread_fifo_priority"] = io_priority;
    result["io_thread_fifo_granted"] = io_priority > 0 && io_refusal.empty();
    result["sim_server_ack_thread_fifo_priority"] = ack_priority;
    result["sim_server_ack_thread_fifo_refused"] = !ack_refusal.empty();
    if (!ack_refusal.empty()) result["sim_server_ack_thread_refusal"] = ack_refusal;
  }
  Terminate(sim);
  std::filesystem::remove_all(dir);
  return result;
}

/// On memq:// with the simulation server in this process, stepped at 60 Hz between the
/// publications (the fallback without a namespace: no transport figure for UDP).
json RoundTripInProcess(double seconds) {
  bus::LcmBus bus("memq://");
  costume::sim_app::SimServerOptions options;
  options.mode = costume::sim_app::Mode::kEditing;
  costume::sim_app::SimServer server(
      bus, costume::assets::ParseSceneText(HangingSheet(), "haptic_bench", "."), options);
  // What the server process's GrabAcknowledger does, on the same in-process bus.
  bus::Publisher<costume_lcm::grab_ack> acks(bus, bus::kGrabAckChannel);
  costume_lcm::grab_ack ack{};
  bus::Subscribe<costume_lcm::grab>(bus, bus::kGrabChannel, [&](const costume_lcm::grab& g) {
    ack.utime = bus::NowUtime();
    ack.grab_seq = g.seq;
    ack.grab_utime = g.utime;
    ack.grab_id = g.grab_id;
    acks.Publish(ack);
  });
  std::int64_t next_frame = SteadyNs();
  return RoundTrip(bus, seconds, [&](std::int64_t until) {
    for (std::int64_t now = SteadyNs(); now < until; now = SteadyNs()) {
      if (now >= next_frame) {
        server.Step();
        next_frame += 16'666'667;
      }
      bus.HandleSubscriptions(0);
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
  });
}

/// Whether a private network namespace can be made here.
bool CanUnshare() { return std::system("unshare -n true >/dev/null 2>&1") == 0; }

/// Re-executes this program inside `unshare -n` with lo up and multicast routed on it.
/// Returns only when that failed.
void ReexecInNamespace(int argc, char** argv) {
  std::vector<std::string> args = {"/usr/bin/unshare", "-n", "sh", "-c",
                                   "ip link set lo up && ip route add 224.0.0.0/4 dev lo && "
                                   "exec \"$0\" \"$@\" --in-netns",
                                   std::filesystem::read_symlink("/proc/self/exe").string()};
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  std::vector<char*> raw;
  for (std::string& a : args) raw.push_back(a.data());
  raw.push_back(nullptr);
  execv(raw[0], raw.data());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"haptic_bench: 1 kHz loop periods, feedback time and the LCM round trip (JSON)"};
  double seconds = 10.0;
  double roundtrip_seconds = 10.0;
  bool skip_loop = false;
  bool skip_roundtrip = false;
  bool in_netns = false;
  bool no_namespace = false;
  int priority = 80;
  int io_priority = 70;
  int ack_priority = 70;
  int repeats = 2000;
  int spin_us = static_cast<int>(kDefaultSpinMargin / 1000);
  double round_seconds = 5.0;
  bool no_floor = false;
  bool attribute_gaps = false;
  std::string sim_server = std::string(COSTUME_BUILD_DIR) + "/sim_core/app/costume_sim_server";
  std::vector<std::string> cases = {"idle", "with_sim_server", "other_core_loaded"};
  app.add_option("--seconds", seconds, "Length of each loop case [s] (the issue's figure: 60)")
      ->check(CLI::PositiveNumber);
  app.add_option("--roundtrip-seconds", roundtrip_seconds, "Length of the round-trip run [s]")
      ->check(CLI::PositiveNumber);
  app.add_option("--cases", cases, "Loop cases: idle, with_sim_server, other_core_loaded");
  app.add_option("--priority", priority, "SCHED_FIFO priority to ask for (0: don't)");
  app.add_option("--spin-us", spin_us,
                 "The hybrid pacer's margin [us], as costume_haptic_server --spin-us (the pure-sleep "
                 "pacer runs beside it)")
      ->check(CLI::Range(0, static_cast<int>(kMaxSpinMarginFraction * 1000)))
      ->capture_default_str();
  app.add_option("--round-seconds", round_seconds,
                 "The variants of a case take turns in segments of about this long [s]")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("--no-floor", no_floor,
               "Only the real loop (both pacers): no bare thread, no clock-spinning thread");
  app.add_flag("--attribute-gaps", attribute_gaps,
               "Each loop variant also reads its thread's /proc schedstat and the CPUs' steal "
               "(/proc/stat) at every tick (about 9 us of work) and reports, per period over "
               "2 ms, the run time, the run-queue delay and the steal over it");
  app.add_option("--io-priority", io_priority,
                 "SCHED_FIFO priority of the round trip's receiving thread, as the haptic "
                 "server's I/O thread (0: don't)");
  app.add_option("--ack-priority", ack_priority,
                 "The simulation server's --ack-priority (its grab acknowledger's SCHED_FIFO "
                 "priority; 0: normal)");
  app.add_option("--repeats", repeats, "Feedback timing repetitions per patch size")
      ->check(CLI::PositiveNumber);
  app.add_option("--sim-server", sim_server, "The costume_sim_server executable");
  app.add_flag("--skip-loop", skip_loop, "No loop cases");
  app.add_flag("--skip-roundtrip", skip_roundtrip, "No round trip");
  app.add_flag("--no-namespace", no_namespace, "Do not re-execute in a network namespace (memq)");
  app.add_flag("--in-netns", in_netns, "(internal) running inside the namespace already");
  CLI11_PARSE(app, argc, argv);

  std::string transport;
  if (in_netns) {
    transport = "udpm://239.255.76.67:7667?ttl=0 inside a private network namespace (unshare -n)";
  } else if (!no_namespace && CanUnshare()) {
    ReexecInNamespace(argc, argv);
    transport = "memq:// (re-executing inside unshare -n failed; the simulation server runs "
                "in-process)";
  } else {
    transport = "memq:// (no network namespace could be made here; the simulation server runs "
                "in-process, so the round trip has no UDP in it)";
  }
  json result;
  result["transport"] = transport;
  const KernelPreemption preemption = ReadKernelPreemption();
  result["kernel_preemption"] = {{"model", preemption.model}, {"source", preemption.source},
                                 {"warning", KernelPreemptionWarning(preemption)}};
  result["feedback"] = json::array({FeedbackTiming(10, 10, repeats), FeedbackTiming(40, 25, repeats),
                                    FeedbackTiming(100, 50, repeats)});
  for (json& f : result["feedback"]) {
    if (f["particles"] == 1000) {
      result["targets_met"]["feedback_1000_particles_under_50us"] =
          f["feedback_us"]["p99"].get<double>() < 50.0;
    }
  }
  if (!skip_loop) {
    for (const std::string& name : cases) {
      pid_t helper = -1;
      if (name == "with_sim_server") {
        helper = Spawn({sim_server, "--builtin", "garment", "--lcm-url",
                        in_netns ? "udpm://239.255.76.67:7667?ttl=0" : "memq://"});
        std::this_thread::sleep_for(std::chrono::seconds(1));  // past its start-up
      } else if (name == "other_core_loaded") {
        helper = StartBusyChild();
      } else if (name != "idle") {
        std::cerr << "haptic_bench: unknown case '" << name << "'\n";
        return 2;
      }
      LoopCaseOptions options;
      options.seconds = seconds;
      options.round_seconds = round_seconds;
      options.priority = priority;
      options.spin_margin = std::int64_t{spin_us} * 1000;
      options.with_floor = !no_floor;
      options.attribute_gaps = attribute_gaps;
      result["loop"][name] = LoopCase(options);
      Terminate(helper);
    }
  }
  if (!skip_roundtrip) {
    result["round_trip"] = in_netns ? RoundTripOverUdp(sim_server, roundtrip_seconds, io_priority, ack_priority)
                                    : RoundTripInProcess(roundtrip_seconds);
  }
  std::cout << result.dump(2) << std::endl;
  return 0;
}
