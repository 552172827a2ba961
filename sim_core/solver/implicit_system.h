#pragma once
/// @file
/// The linear system of one backward-Euler step linearised once (Baraff & Witkin 1998,
/// eq. 18): A = M − h ∂f/∂v − h² ∂f/∂x, b = h (f₀ + h ∂f/∂x v₀), for any model (level 0 or a
/// coarse level of the pyramid).

#include <Eigen/Core>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"
#include "sim_core/solver/spring_forces.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

/// Writes A into `a` (built for `model`) and b into `b` (3n) at `state` for step h [s]:
/// springs with axial damping, gravity and, when enabled, air drag. Never allocates.
void AssembleImplicitSystem(const ClothModel& model, const ClothState& state, double h,
                            JacobianMode mode, const ExternalForces& external, SystemMatrix& a,
                            Eigen::VectorXd& b);

}  // namespace costume::sim
