#pragma once
/// @file
/// The 1 kHz loop: paced on an absolute clock (clock_nanosleep TIMER_ABSTIME on
/// CLOCK_MONOTONIC), so a late wake-up never shifts later deadlines and lag never accumulates;
/// a tick that wakes more than a period late skips the deadlines it missed and counts them.
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
  std::int64_t Now() override { return now_; }
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
  std::unique_ptr<std::int64_t[]> script_ = std::make_unique<std::int64_t[]>(kMaxScript);
  int script_size_ = 0;
  int script_next_ = 0;
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
};

/// The fixed-rate loop. Run() ticks on the calling thread; Start()/Stop() on its own thread.
class HapticLoop {
 public:
  /// `clock` and `handler` must outlive the loop. Throws costume::sim::InputError for a
  /// non-positive period or ring capacity. Allocates the ring here, never later.
  HapticLoop(LoopClock& clock, TickHandler& handler, const HapticLoopOptions& options);
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  /// Ticks `num_ticks` times (< 0: until RequestStop) on the calling thread, first deadline
  /// one period from now. Never allocates; never throws (the handler must not either).
  void Run(std::int64_t num_ticks);
  /// Asks Run to return after the current tick. Thread-safe.
  void RequestStop() { stop_.store(true, std::memory_order_relaxed); }

  /// Starts a thread that calls TryRealtimePriority (if asked) and then Run(-1).
  void Start();
  /// RequestStop and join. No-op when not started.
  void Stop();
  /// The thread's real-time status once Start has run it (valid after the first tick).
  RealtimeStatus realtime_status() const;

  LoopCounters counters() const;
  /// Statistics of the recorded periods (allocates; any thread, any time; a snapshot taken
  /// while ticking may mix one or two periods from consecutive ticks, harmless for statistics).
  PeriodStatistics Statistics() const;
  /// Statistics of the periods recorded from the `first`-th on (0-based, as counted by
  /// num_recorded(); periods already overwritten in the ring are left out). The status
  /// message uses it for the periods of one status period. Allocates; any thread.
  PeriodStatistics StatisticsSince(std::int64_t first) const;
  /// Periods recorded since construction or ResetStatistics (any thread).
  std::int64_t num_recorded() const { return num_recorded_.load(std::memory_order_acquire); }
  /// Forget recorded periods and counters (e.g. after a warm-up). Only while not running.
  void ResetStatistics();

 private:
  void RecordPeriod(std::int64_t period);

  LoopClock& clock_;
  TickHandler& handler_;
  HapticLoopOptions options_;
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
