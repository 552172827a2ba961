#pragma once
/// @file
/// A cloth particle touching an obstacle, as the implicit solve sees it.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace costume::sim {

struct Contact {
  int particle = 0;
  /// Outward unit normal of the obstacle at the contact [-].
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
  /// Normal velocity the particle must have after the step [m/s]: the velocity that brings
  /// it exactly to the surface (thickness included) within the step, so contacts are
  /// resolved inside the solve rather than by a later push.
  double target_normal_velocity = 0.0;
  /// Coulomb friction coefficient of this contact [-]; 0 for none.
  double friction = 0.0;
  /// Normal impulse this particle's contact delivered in the previous step [N·s] (0 if it
  /// was not in contact): the normal force estimate that bounds friction in this step.
  double previous_normal_impulse = 0.0;
  /// Normal impulse the constraint delivered in this step [N·s] (> 0 pushes out); filled
  /// by the stepper.
  double normal_impulse = 0.0;
};

/// The friction coefficient of a fabric of coefficient `fabric` on an obstacle of
/// coefficient `obstacle` (the avatar's skin, a sphere) [-]: their geometric mean, Box2D's
/// mixing rule (b2MixFriction). Either at 0 gives 0 (a frictionless body, or fabric), equal
/// coefficients give that coefficient, and a slippery fabric slides on any body.
inline double MixFriction(double fabric, double obstacle) {
  return std::sqrt(std::max(0.0, fabric) * std::max(0.0, obstacle));
}

}  // namespace costume::sim
