#pragma once
/// @file
/// Cloth threaded round a limb: a structural spring whose two ends are outside the true
/// skinned mesh while its midpoint is deep inside it, so the limb passed between them. The
/// particles' own depths, which the penetration oracle checks, do not show it.

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/collision/mesh_distance.h"

namespace costume::test {

/// Structural springs of `model` at `x` with both ends at most 2 mm inside `skin` and the
/// midpoint more than `depth` [m] inside. Springs shorter than 2 cm are skipped: they cannot
/// straddle a limb.
inline int CountThreadedSprings(const sim::ClothModel& model, const sim::Points& x,
                                const sim::MeshDistance& skin, double depth = 0.01) {
  constexpr double kReach = 0.1;  // the oracle's search radius [m]
  int threaded = 0;
  for (const sim::Spring& s : model.springs()) {
    if (s.kind != sim::SpringKind::kStructural) continue;
    const Eigen::Vector3d a = x.row(s.a).transpose(), b = x.row(s.b).transpose();
    if ((b - a).norm() < 0.02 || skin.PenetrationDepth(0.5 * (a + b), kReach) <= depth) continue;
    if (skin.PenetrationDepth(a, kReach) <= 0.002 && skin.PenetrationDepth(b, kReach) <= 0.002) {
      ++threaded;
    }
  }
  return threaded;
}

}  // namespace costume::test
