#pragma once
/// @file
/// A smooth deformation of a flat sheet in the x–z plane, for the pyramid tests: every level
/// of a pyramid sees the same field, so one implicit step of a coarse level can be compared
/// with the finer level's step restricted to it.

#include <cmath>
#include <numbers>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"

namespace costume::test {

/// Displacement ε·(sin πx cos πz, cos πx sin πz) in (x, z) plus a small shear, and a smooth
/// velocity field.
inline sim::ClothState SmoothState(const sim::ClothModel& model) {
  sim::ClothState state = sim::ClothState::AtRest(model);
  const double pi = std::numbers::pi;
  for (int i = 0; i < model.num_particles(); ++i) {
    const double x = model.rest_positions()(i, 0), z = model.rest_positions()(i, 2);
    state.positions(i, 0) += 2e-3 * std::sin(pi * x) * std::cos(pi * z) + 1e-3 * z;
    state.positions(i, 2) += 2e-3 * std::cos(pi * x) * std::sin(pi * z);
    state.velocities(i, 0) = 0.01 * std::cos(pi * z);
    state.velocities(i, 2) = -0.01 * std::sin(pi * x);
  }
  return state;
}

}  // namespace costume::test
