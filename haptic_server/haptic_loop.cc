#include "haptic_server/haptic_loop.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <vector>

#include "sim_core/common/input_error.h"
#include "sim_core/common/monotonic_clock.h"
#include "sim_core/common/percentile.h"

namespace costume::haptics {

namespace {
using sim::kNanosPerSecond;

/// Tells the core it is in a spin-wait (x86 PAUSE, ARM YIELD): the hyperthread sibling or the
/// hypervisor may use the slot, and leaving the loop does not flush the pipeline.
inline void CpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
  asm volatile("yield");
#endif
}

/// Relaxed increment by the only writer (no read-modify-write needed, nor wanted in the tick).
inline void AddRelaxed(std::atomic<std::int64_t>& counter, std::int64_t value) {
  counter.store(counter.load(std::memory_order_relaxed) + value, std::memory_order_relaxed);
}

/// The options after checking the period and the ring (before the pacer checks its margin).
const HapticLoopOptions& CheckedLoopOptions(const HapticLoopOptions& options) {
  if (options.period <= 0 || options.ring_capacity <= 0) {
    throw sim::InputError("haptic loop: period = " + std::to_string(options.period) +
                          " ns and ring_capacity = " + std::to_string(options.ring_capacity) +
                          " must both be > 0");
  }
  return options;
}
}  // namespace

std::int64_t MonotonicClock::Now() { return sim::MonotonicNs(); }

void MonotonicClock::SleepUntil(std::int64_t deadline) { sim::SleepUntilNs(deadline); }

void FakeClock::SleepUntil(std::int64_t deadline) {
  now_ = std::max(now_, deadline);
  if (script_next_ < script_size_) now_ += script_[script_next_++];
}

void FakeClock::ScriptLatencies(const std::int64_t* latencies, int count) {
  script_size_ = std::min(count, kMaxScript);
  std::copy(latencies, latencies + script_size_, script_.get());
  script_next_ = 0;
}

Pacer::Pacer(LoopClock& clock, std::int64_t spin_margin, std::int64_t period)
    : clock_(clock), configured_margin_(spin_margin), spin_margin_(spin_margin) {
  const auto max_margin =
      static_cast<std::int64_t>(kMaxSpinMarginFraction * static_cast<double>(period));
  if (period <= 0 || spin_margin < 0 || spin_margin > max_margin) {
    throw sim::InputError("haptic loop: spin margin = " + std::to_string(spin_margin) +
                          " ns must be in [0, " + std::to_string(max_margin) +
                          "] ns (0: sleep only; at most " +
                          std::to_string(static_cast<int>(kMaxSpinMarginFraction * 100)) +
                          " % of the period " + std::to_string(period) + " ns)");
  }
}

std::int64_t Pacer::WaitUntil(std::int64_t deadline) {
  AddRelaxed(num_waits_, 1);
  const std::int64_t margin = spin_margin_.load(std::memory_order_relaxed);
  if (margin == 0) {
    clock_.SleepUntil(deadline);
    return clock_.Now();
  }
  // An absolute sleep to a time already past returns at once, so no check of "now" first.
  clock_.SleepUntil(deadline - margin);
  const std::int64_t woke = clock_.Now();
  if (woke >= deadline) {
    AddRelaxed(num_margin_exceeded_, 1);
    return woke;
  }
  std::int64_t now = woke;
  while (now < deadline) {
    CpuRelax();
    now = clock_.Now();
  }
  AddRelaxed(spin_ns_, now - woke);
  return now;
}

PacerCounters Pacer::counters() const {
  return {num_waits_.load(std::memory_order_relaxed),
          num_margin_exceeded_.load(std::memory_order_relaxed),
          spin_ns_.load(std::memory_order_relaxed)};
}

void Pacer::Reset() {
  num_waits_.store(0);
  num_margin_exceeded_.store(0);
  spin_ns_.store(0);
}

std::string TryThreadFifoPriority(int priority) {
  sched_param param{};
  param.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (error == 0) return "";
  return std::string("SCHED_FIFO priority ") + std::to_string(priority) + " refused: " +
         std::strerror(error) +
         "; grant CAP_SYS_NICE (setcap cap_sys_nice+ep <program>) or an rtprio "
         "limit in /etc/security/limits.conf. Running at normal priority.";
}

RealtimeStatus TryRealtimePriority(int priority) {
  RealtimeStatus status;
  status.priority = priority;
  status.reason = TryThreadFifoPriority(priority);
  status.realtime = status.reason.empty();
  status.memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
  if (!status.memory_locked) {
    const int lock_error = errno;
    if (!status.reason.empty()) status.reason += " ";
    status.reason += std::string("mlockall refused: ") + std::strerror(lock_error) +
                     "; raise the memlock limit (ulimit -l) to avoid page faults in the tick.";
  }
  return status;
}

std::int64_t NearestRankPercentile(const std::int64_t* sorted, std::int64_t n, double q) {
  return sim::NearestRankPercentile(sorted, n, q);
}

PeriodStatistics ComputePeriodStatistics(const std::int64_t* periods, std::int64_t n,
                                         std::int64_t nominal) {
  PeriodStatistics stats;
  stats.nominal = nominal;
  stats.num_samples = n;
  if (n <= 0) return stats;
  std::vector<std::int64_t> sorted(periods, periods + n);
  std::sort(sorted.begin(), sorted.end());
  stats.min = sorted.front();
  stats.max = sorted.back();
  stats.p50 = NearestRankPercentile(sorted.data(), n, 0.50);
  stats.p99 = NearestRankPercentile(sorted.data(), n, 0.99);
  stats.p999 = NearestRankPercentile(sorted.data(), n, 0.999);
  double sum = 0.0;
  for (std::int64_t p : sorted) {
    sum += static_cast<double>(p);
    stats.num_gaps += p > 2 * nominal ? 1 : 0;
  }
  stats.mean = sum / static_cast<double>(n);
  for (std::int64_t& p : sorted) p = std::abs(p - nominal);
  std::sort(sorted.begin(), sorted.end());
  stats.error_p999 = NearestRankPercentile(sorted.data(), n, 0.999);
  stats.error_max = sorted.back();
  return stats;
}

HapticLoop::HapticLoop(LoopClock& clock, TickHandler& handler, const HapticLoopOptions& options)
    : clock_(clock),
      handler_(handler),
      options_(CheckedLoopOptions(options)),
      pacer_(clock, options_.spin_margin, options_.period) {
  ring_ = std::make_unique<std::atomic<std::int64_t>[]>(options_.ring_capacity);
}

HapticLoop::~HapticLoop() { Stop(); }

void HapticLoop::RecordPeriod(std::int64_t period) {
  const std::int64_t k = num_recorded_.load(std::memory_order_relaxed);
  ring_[k % options_.ring_capacity].store(period, std::memory_order_relaxed);
  num_recorded_.store(k + 1, std::memory_order_release);
}

void HapticLoop::Run(std::int64_t num_ticks) {
  const std::int64_t period = options_.period;
  const double period_s = static_cast<double>(period) / kNanosPerSecond;
  std::int64_t deadline = clock_.Now() + period;
  std::int64_t previous_wake = -1;
  for (std::int64_t k = 0; num_ticks < 0 || k < num_ticks; ++k) {
    if (stop_.load(std::memory_order_relaxed)) break;
    const std::int64_t now = pacer_.WaitUntil(deadline);
    if (previous_wake >= 0) RecordPeriod(now - previous_wake);
    previous_wake = now;
    // More than a period late: skip the deadlines already gone instead of racing to catch up.
    const std::int64_t missed = (now - deadline) / period;
    if (missed > 0) {
      num_missed_.fetch_add(missed, std::memory_order_relaxed);
      deadline += missed * period;
    }
    handler_.Tick(TickInfo{num_ticks_.load(std::memory_order_relaxed), now, deadline, period_s});
    num_ticks_.fetch_add(1, std::memory_order_relaxed);
    deadline += period;
    if (clock_.Now() > deadline) num_overruns_.fetch_add(1, std::memory_order_relaxed);
  }
}

void HapticLoop::Start() {
  if (thread_.joinable()) return;
  stop_.store(false, std::memory_order_relaxed);
  thread_ = std::thread([this] {
    if (options_.realtime_priority > 0) {
      status_ = TryRealtimePriority(options_.realtime_priority);
    } else {
      status_.reason = "real-time priority not requested.";
    }
    // Spinning pays only at real-time priority (HapticLoopOptions::spin_margin).
    pacer_.EnableSpinning(status_.realtime);
    if (!status_.realtime && options_.spin_margin > 0) {
      status_.reason += " The pacer sleeps only: no spinning at normal priority.";
    }
    status_ready_.store(true, std::memory_order_release);
    Run(-1);
  });
}

void HapticLoop::Stop() {
  if (!thread_.joinable()) return;
  RequestStop();
  thread_.join();
}

RealtimeStatus HapticLoop::realtime_status() const {
  if (!status_ready_.load(std::memory_order_acquire)) return {};
  return status_;
}

LoopCounters HapticLoop::counters() const {
  return {num_ticks_.load(std::memory_order_relaxed), num_missed_.load(std::memory_order_relaxed),
          num_overruns_.load(std::memory_order_relaxed)};
}

PeriodStatistics HapticLoop::Statistics() const { return StatisticsSince(0); }

PeriodStatistics HapticLoop::StatisticsSince(std::int64_t first) const {
  const std::int64_t recorded = num_recorded_.load(std::memory_order_acquire);
  const std::int64_t begin = std::max({first, recorded - options_.ring_capacity, std::int64_t{0}});
  const std::int64_t n = std::max<std::int64_t>(0, recorded - begin);
  std::vector<std::int64_t> periods(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i) {
    periods[i] = ring_[(begin + i) % options_.ring_capacity].load(std::memory_order_relaxed);
  }
  return ComputePeriodStatistics(periods.data(), n, options_.period);
}

void HapticLoop::ResetStatistics() {
  num_recorded_.store(0);
  num_ticks_.store(0);
  num_missed_.store(0);
  num_overruns_.store(0);
  pacer_.Reset();
}

}  // namespace costume::haptics
