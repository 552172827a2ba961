#pragma once
/// @file
/// The mutable state of a cloth: everything a replay needs, nothing else.

#include <Eigen/Core>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// Positions and velocities of a cloth's particles and the simulated time.
struct ClothState {
  /// Positions (n×3) [m], world frame, y up.
  Points positions;
  /// Velocities (n×3) [m/s].
  Points velocities;
  /// Simulated time [s].
  double time = 0.0;

  /// The state at rest: rest positions, zero velocity, t = 0.
  static ClothState AtRest(const ClothModel& model) {
    ClothState state;
    state.positions = model.rest_positions();
    state.velocities = Points::Zero(model.num_particles(), 3);
    return state;
  }
};

}  // namespace costume::sim
