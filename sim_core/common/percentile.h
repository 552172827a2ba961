#pragma once
/// @file
/// The nearest-rank percentile, the one definition every reported p50/p99/p99.9 uses (the
/// haptic loop's period statistics, the simulation server's frame periods), so that figures
/// from the two processes mean the same thing.

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace costume::sim {

/// Element ceil(q·n) − 1 of the ascending `sorted` (n > 0 elements), q in (0, 1]; the rank is
/// clamped to [0, n − 1]. Never throws; never allocates.
template <typename T>
T NearestRankPercentile(const T* sorted, std::int64_t n, double q) {
  const auto rank = static_cast<std::int64_t>(std::ceil(q * static_cast<double>(n)));
  return sorted[std::clamp<std::int64_t>(rank - 1, 0, n - 1)];
}

}  // namespace costume::sim
