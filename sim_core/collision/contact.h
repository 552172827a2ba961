#pragma once
/// @file
/// A cloth particle touching an obstacle, as the implicit solve sees it.

#include <Eigen/Core>
#include <limits>
#include <algorithm>
#include <cmath>

namespace costume::sim {

struct Contact {
  int particle = 0;
  /// Outward unit normal of the obstacle at the contact [-].
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
  /// Normal velocity the particle must have after the step [m/s]: the body's contacts'
  /// ContactNormalVelocity, a sphere's the one that lands the particle on its shell within
  /// the step. Contacts are resolved inside the solve rather than by a later push.
  double target_normal_velocity = 0.0;
  /// Coulomb friction coefficient of this contact [-]; 0 for none.
  double friction = 0.0;
  /// Normal impulse this particle's contact delivered in the previous step [N·s] (0 if it
  /// was not in contact): the normal force estimate that bounds friction in this step.
  double previous_normal_impulse = 0.0;
  /// Normal impulse the constraint delivered in this step [N·s] (> 0 pushes out); filled
  /// by the stepper.
  double normal_impulse = 0.0;
  /// Where the obstacle's shell (its surface + the cloth's thickness) lies at the end of the
  /// step, as the plane normal·x = shell_offset [m] through the nearest shell point: what
  /// the corrections after the solve (the strain limit) keep the particle outside of.
  /// −inf: no plane (nothing is held).
  double shell_offset = -std::numeric_limits<double>::infinity();
};

/// The normal velocity a contact prescribes [m/s] for a particle `gap` [m] outside the
/// obstacle's shell (< 0: inside it) whose normal velocity relative to the obstacle's surface
/// is `relative_normal_velocity` [m/s] (> 0: leaving it), over a step of `h` [s] > 0, on a
/// surface moving at `surface_normal_velocity` [m/s] along the outward normal. Inside the
/// shell, the velocity that brings the particle onto it within the step. Outside, the
/// particle's own, slowed only as far as lands it on the shell: a contact never pulls cloth
/// towards the obstacle. Used by the body's colliders; a sphere still lands every contact on
/// its shell (with this rule its drape's solve took a third more iterations).
/// Why not land every contact on the shell: cloth within the margin, resting or leaving,
/// was then pulled onto the body at up to margin / h (12 cm/s). A skirt clung to the walking
/// legs, 25 % of its particles against the shell where the mesh method had 4 %, and
/// crumpled (docs/collision.md, "Contacts that pulled").
inline double ContactNormalVelocity(double surface_normal_velocity, double gap,
                                    double relative_normal_velocity, double h) {
  const double landing = -gap / h;
  return surface_normal_velocity +
         (gap <= 0.0 ? landing : std::max(relative_normal_velocity, landing));
}

/// The friction coefficient of a fabric of coefficient `fabric` on an obstacle of
/// coefficient `obstacle` (the avatar's skin, a sphere) [-]: their geometric mean, Box2D's
/// mixing rule (b2MixFriction). Either at 0 gives 0 (a frictionless body, or fabric), equal
/// coefficients give that coefficient, and a slippery fabric slides on any body.
inline double MixFriction(double fabric, double obstacle) {
  return std::sqrt(std::max(0.0, fabric) * std::max(0.0, obstacle));
}

}  // namespace costume::sim
