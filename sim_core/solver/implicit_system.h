#pragma once
/// @file
/// The linear system of one backward-Euler step linearised once (Baraff & Witkin 1998,
/// eq. 18): A = M − h ∂f/∂v − h² ∂f/∂x, b = h (f₀ + h ∂f/∂x v₀), for any model (level 0 or a
/// coarse level of the pyramid).

#include <Eigen/Core>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"
#include "sim_core/common/thread_pool.h"
#include "sim_core/solver/spring_forces.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

/// Writes A into `a` (built for `model`) and b into `b` (3n) at `state` for step h [s]:
/// springs with axial damping, gravity and, when enabled, air drag. `spring_rhs` (3 per
/// spring) holds each spring's share of b between its two passes. The particles' and the
/// springs' loops run on `pool` when given; every sum is made in the order of the serial
/// loops (particle terms first, then the springs in their order), the same bits with any
/// thread count. Never allocates.
void AssembleImplicitSystem(const ClothModel& model, const ClothState& state, double h,
                            JacobianMode mode, const ExternalForces& external, SystemMatrix& a,
                            Eigen::VectorXd& b, Eigen::VectorXd& spring_rhs,
                            ThreadPool* pool = nullptr);

/// The same on this thread with its own scratch (allocates it: tests and one-off uses).
void AssembleImplicitSystem(const ClothModel& model, const ClothState& state, double h,
                            JacobianMode mode, const ExternalForces& external, SystemMatrix& a,
                            Eigen::VectorXd& b);

}  // namespace costume::sim
