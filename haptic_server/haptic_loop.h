#pragma once
/// @file
/// The 1 kHz loop: paced on an absolute clock (clock_nanosleep TIMER_ABSTIME on
/// CLOCK_MONOTONIC), so a late wake-up never shifts later deadlines and lag never accumulates;
/// a tick that wakes more than a period late skips the deadlines it missed and counts them.
/// Pacing may be hybrid (Pacer): sleep until a margin before the deadline, then spin on the
/// clock, so the sleep's wake-up latency is absorbed by the spin instead of the period.
/// The loop itself never allocates, locks or throws once running; the period of every tick is
/// written to a preallocated ring from which PeriodStatistics are computed outside the tick.
/// Outgoing data leaves the tick through SpscQueue (lock_free.h), never by publishing inside it.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

namespace costume::haptics {

/// A monotonic time source with absolute sleeps, in nanoseconds. Real or fake.
class LoopClock {
 public:
  virtual ~LoopClock() = default;
  /// Now [ns] on a monotonic clock (origin unspecified). Never throws; never allocates.
  virtual std::int64_t Now() = 0;
  /// Returns no earlier than `deadline` [ns] (same origin as Now). Never throws.
  virtual void SleepUntil(std::int64_t deadline) = 0;
};

/// CLOCK_MONOTONIC and clock_nanosleep(TIMER_ABSTIME) (retried on EINTR). Thread-safe.
class MonotonicClock final : public LoopClock {
 public:
  std::int64_t Now() override;
  void SleepUntil(std::int64_t deadline) override;
};

/// A test clock: SleepUntil jumps straight to the deadline, plus a scripted wake-up latency.
/// Not thread-safe (one loop, one thread).
class FakeClock final : public LoopClock {
 public:
  explicit FakeClock(std::int64_t start = 0) : now_(start) {}
  /// The time, after which the clock moves on by the read cost (SetReadCost).
  std::int64_t Now() override {
    const std::int64_t now = now_;
    now_ += read_cost_;
    return now;
  }
  /// Every Now() moves time on by `cost` [ns] >= 0 (0 by default: time moves only by sleeps
  /// and Advance). A Pacer that spins needs cost > 0, as a real clock read takes time;
  /// with 0 its spin would never reach the deadline.
  void SetReadCost(std::int64_t cost) { read_cost_ = cost; }
  /// now = max(now, deadline) + the next latency of the script (0 once it is used up).
  void SleepUntil(std::int64_t deadline) override;
  /// Moves time forward by `duration` [ns] (e.g. a tick handler simulating work).
  void Advance(std::int64_t duration) { now_ += duration; }
  /// Wake-up latencies [ns] for the following SleepUntil calls, in order. Copies `count`
  /// values into preallocated storage (up to kMaxScript).
  void ScriptLatencies(const std::int64_t* latencies, int count);
  static constexpr int kMaxScript = 1 << 16;

 private:
  std::int64_t now_;
  std::int64_t read_cost_ = 0;
  std::unique_ptr<std::int64_t[]> script_ = std::make_unique<std::int64_t[]>(kMaxScript);
  int script_size_ = 0;
  int script_next_ = 0;
};

/// The largest spin margin a Pacer accepts, as a fraction of the period: beyond half the
/// period the loop would spin for most of it, a core given to waiting (and a SCHED_FIFO thread
/// that never sleeps is throttled by the kernel, sched_rt_runtime_us).
inline constexpr double kMaxSpinMarginFraction = 0.5;

/// The spin margin costume_haptic_server uses by default [ns] (--spin-us). Chosen from a sweep
/// on the development VM (docs/processes.md, "Benchmark"): below it the sleep overshoots the
/// margin often (2.3 % of the sleeps at 50 µs), at 100 µs 0.3 %, and 200–300 µs only bring
/// that to 0.1 % at 2.4–3.7 times the spinning. It costs the margin less the sleep's usual
/// wake-up latency per period: 7–8 % of one core at 1 kHz there.
inline constexpr std::int64_t kDefaultSpinMargin = 100'000;

/// What a Pacer has done since construction or Reset (readable from any thread).
struct PacerCounters {
  /// WaitUntil calls.
  std::int64_t num_waits = 0;
  /// Waits whose sleep woke at or after the deadline although it aimed `spin_margin` before
  /// it: the wake-up latency exceeded the margin (always 0 with a margin of 0).
  std::int64_t num_margin_exceeded = 0;
  /// Time spent spinning [ns]: the CPU the margin costs (over wall time: fraction of a core).
  std::int64_t spin_ns = 0;
};

/// Hybrid pacing, as vendor servo loops do it: clock_nanosleep until `spin_margin` before the
/// deadline, then read the clock in a loop until the deadline. The sleep alone wakes tens to
/// hundreds of µs late on a loaded or virtual machine, and that latency varies from tick to
/// tick (period error); with the spin it only has to be shorter than the margin. A margin of 0
/// is pure sleeping. The margin's price is CPU: up to the margin per period.
/// One thread waits (the loop's); never allocates, locks or throws once constructed.
class Pacer {
 public:
  /// `clock` must outlive the pacer. Throws costume::sim::InputError unless
  /// 0 <= spin_margin <= kMaxSpinMarginFraction · period (both [ns], period > 0).
  Pacer(LoopClock& clock, std::int64_t spin_margin, std::int64_t period);
  /// Returns the first clock reading at or after `deadline` [ns]: never earlier. (Later when
  /// the sleep woke late, or when the deadline was already past.)
  std::int64_t WaitUntil(std::int64_t deadline);
  std::int64_t spin_margin() const { return spin_margin_.load(std::memory_order_relaxed); }
  /// Sets the margin to 0 (sleep only) or back to the constructor's. Only while nobody waits.
  void EnableSpinning(bool enable) {
    spin_margin_.store(enable ? configured_margin_ : 0, std::memory_order_relaxed);
  }
  PacerCounters counters() const;
  /// Zeroes the counters (only while nobody waits).
  void Reset();

 private:
  LoopClock& clock_;
  std::int64_t configured_margin_;
  std::atomic<std::int64_t> spin_margin_;
  // Written by the waiting thread only (load + store, no read-modify-write); read by others.
  std::atomic<std::int64_t> num_waits_{0};
  std::atomic<std::int64_t> num_margin_exceeded_{0};
  std::atomic<std::int64_t> spin_ns_{0};
};

/// What the loop tells a tick.
struct TickInfo {
  /// Tick number, from 0.
  std::int64_t index = 0;
  /// Clock when the tick woke [ns].
  std::int64_t now = 0;
  /// The deadline this tick was scheduled for [ns] (now − deadline is the wake-up latency).
  std::int64_t deadline = 0;
  /// Nominal period [s].
  double period = 1e-3;
};

/// The work of one tick. Must return well within a period; must not allocate, lock or throw.
class TickHandler {
 public:
  virtual ~TickHandler() = default;
  virtual void Tick(const TickInfo& info) = 0;
};

/// Whether the loop thread got real-time scheduling, and why not.
struct RealtimeStatus {
  /// SCHED_FIFO was granted.
  bool realtime = false;
  /// The SCHED_FIFO priority asked for.
  int priority = 0;
  /// mlockall(MCL_CURRENT | MCL_FUTURE) succeeded (no page faults in the tick).
  bool memory_locked = false;
  /// Empty when everything was granted; otherwise what failed, the errno text and the remedy
  /// (e.g. "SCHED_FIFO refused: Operation not permitted; grant CAP_SYS_NICE or an rtprio
  /// limit in /etc/security/limits.conf").
  std::string reason;
};

/// Asks for SCHED_FIFO at `priority` (1..99) for the calling thread only (no memory locking:
/// for threads beside the tick, e.g. the LCM I/O thread). Returns "" when granted, otherwise
/// what was refused, the errno text and the remedy. Allocates the text; never throws.
std::string TryThreadFifoPriority(int priority);

/// Asks for SCHED_FIFO at `priority` for the calling thread and locks memory; reports instead
/// of throwing. Call on the loop thread before it starts ticking (allocates the reason text).
RealtimeStatus TryRealtimePriority(int priority);

/// Tick-period statistics [ns] over the samples in the ring (the most recent ones).
struct PeriodStatistics {
  std::int64_t num_samples = 0;
  std::int64_t nominal = 0;
  std::int64_t min = 0;
  std::int64_t p50 = 0;
  std::int64_t p99 = 0;
  std::int64_t p999 = 0;
  std::int64_t max = 0;
  double mean = 0.0;
  /// 99.9th percentile and maximum of |period − nominal|.
  std::int64_t error_p999 = 0;
  std::int64_t error_max = 0;
  /// Periods longer than twice the nominal one (gaps the hand may feel).
  std::int64_t num_gaps = 0;
};

/// Nearest-rank percentile of ascending `sorted` (n > 0): element ceil(q·n) − 1, q in (0, 1].
std::int64_t NearestRankPercentile(const std::int64_t* sorted, std::int64_t n, double q);

/// Statistics of `periods` (n samples [ns]) against `nominal` [ns]. Allocates (copies and
/// sorts); call outside the tick.
PeriodStatistics ComputePeriodStatistics(const std::int64_t* periods, std::int64_t n,
                                         std::int64_t nominal);

/// Counters of a running loop (each readable from another thread).
struct LoopCounters {
  std::int64_t num_ticks = 0;
  /// Deadlines skipped because a wake-up came more than a period late.
  std::int64_t num_missed = 0;
  /// Ticks whose work ended after the next deadline.
  std::int64_t num_overruns = 0;
};

/// Options of HapticLoop.
struct HapticLoopOptions {
  /// Period [ns] > 0: 1 ms for 1 kHz.
  std::int64_t period = 1'000'000;
  /// Periods kept for statistics (the ring's size, > 0): 2^16 covers 65 s at 1 kHz.
  std::int64_t ring_capacity = 1 << 16;
  /// Start(): try SCHED_FIFO at this priority (1..99); <= 0 to stay at normal priority.
  int realtime_priority = 80;
  /// Pacer margin [ns]: sleep until this long before each deadline, then spin on the clock.
  /// 0 (the default here) sleeps all the way; costume_haptic_server uses kDefaultSpinMargin.
  /// 0 ..kMaxSpinMarginFraction · period. Start() spins only when SCHED_FIFO was granted:
  /// at normal priority the spin competes with every other thread, and measured under load it
  /// made missed ticks more frequent, not less (docs/processes.md, "Benchmark").
  std::int64_t spin_margin = 0;
};

/// The fixed-rate loop. Run() ticks on the calling thread; Start()/Stop() on its own thread.
class HapticLoop {
 public:
  /// `clock` and `handler` must outlive the loop. Throws costume::sim::InputError for a
  /// non-positive period or ring capacity or a spin margin out of range. Allocates the ring
  /// here, never later.
  HapticLoop(LoopClock& clock, TickHandler& handler, const HapticLoopOptions& options);
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  /// Ticks `num_ticks` times (< 0: until RequestStop) on the calling thread, first deadline
  /// one period from now. Never allocates; never throws (the handler must not either).
  void Run(std::int64_t num_ticks);
  /// Asks Run to return after the current tick. Thread-safe.
  void RequestStop() { stop_.store(true, std::memory_order_relaxed); }

  /// Starts a thread that calls TryRealtimePriority (if asked) and then Run(-1), with the
  /// pacer's spinning off unless SCHED_FIFO was granted (the status's reason then says so).
  void Start();
  /// RequestStop and join. No-op when not started.
  void Stop();
  /// The thread's real-time status once Start has run it (valid after the first tick).
  RealtimeStatus realtime_status() const;

  LoopCounters counters() const;
  /// The pacer's counters: how often the sleep overshot the margin, time spent spinning.
  PacerCounters pacer_counters() const { return pacer_.counters(); }
  /// The spin margin in use [ns]: options.spin_margin, or 0 after Start at normal priority.
  std::int64_t spin_margin() const { return pacer_.spin_margin(); }
  /// Statistics of the recorded periods (allocates; any thread, any time; a snapshot taken
  /// while ticking may mix one or two periods from consecutive ticks, harmless for statistics).
  PeriodStatistics Statistics() const;
  /// Statistics of the periods recorded from the `first`-th on (0-based, as counted by
  /// num_recorded(); periods already overwritten in the ring are left out). The status
  /// message uses it for the periods of one status period. Allocates; any thread.
  PeriodStatistics StatisticsSince(std::int64_t first) const;
  /// Periods recorded since construction or ResetStatistics (any thread).
  std::int64_t num_recorded() const { return num_recorded_.load(std::memory_order_acquire); }
  /// Forget recorded periods and counters, the pacer's too (e.g. after a warm-up). Only
  /// while not running.
  void ResetStatistics();

 private:
  void RecordPeriod(std::int64_t period);

  LoopClock& clock_;
  TickHandler& handler_;
  HapticLoopOptions options_;
  Pacer pacer_;
  std::unique_ptr<std::atomic<std::int64_t>[]> ring_;
  std::atomic<std::int64_t> num_recorded_{0};
  std::atomic<std::int64_t> num_ticks_{0};
  std::atomic<std::int64_t> num_missed_{0};
  std::atomic<std::int64_t> num_overruns_{0};
  std::atomic<bool> stop_{false};
  std::atomic<bool> status_ready_{false};
  RealtimeStatus status_;
  std::thread thread_;
};

}  // namespace costume::haptics
