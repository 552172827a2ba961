#pragma once
/// @file
/// CLOCK_MONOTONIC in integer nanoseconds and an absolute sleep on it: the one clock the
/// simulation server's 60 Hz loop, the haptic server's 1 kHz loop and the benchmarks pace on.

#include <time.h>

#include <cerrno>
#include <cstdint>

namespace costume::sim {

inline constexpr std::int64_t kNanosPerSecond = 1'000'000'000;

/// CLOCK_MONOTONIC now [ns].
inline std::int64_t MonotonicNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNanosPerSecond + ts.tv_nsec;
}

/// Sleeps until CLOCK_MONOTONIC reaches `deadline` [ns]; at once if it has. Absolute, so a
/// signal that interrupts the sleep sleeps again to the same deadline, and loops paced on it
/// accumulate no drift.
inline void SleepUntilNs(std::int64_t deadline) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline / kNanosPerSecond);
  ts.tv_nsec = static_cast<long>(deadline % kNanosPerSecond);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace costume::sim
