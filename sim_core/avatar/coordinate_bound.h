#pragma once
/// @file
/// The bound on a body's coordinates (kMaxCoordinate) as avatars, skeletons and clips check
/// it, with one message form.

#include <Eigen/Core>
#include <string>

#include "sim_core/common/input_error.h"

namespace costume::sim {

/// Throws InputError "<what> <c> m (allowed: within ±10000 m of <origin>)" when the largest
/// coordinate c of `v` (finite, checked before) lies beyond kMaxCoordinate. The largest
/// coordinate, not the norm: the norm overflows first (2.5e298 m would read as inf).
inline void RequireWithinReach(const Eigen::Vector3d& v, const std::string& what,
                               const std::string& origin) {
  const double largest = v.lpNorm<Eigen::Infinity>();
  if (largest <= kMaxCoordinate) return;
  throw InputError(what + " " + FormatValue(largest) + " m (allowed: within ±" +
                   FormatValue(kMaxCoordinate) + " m of " + origin + ")");
}

}  // namespace costume::sim
