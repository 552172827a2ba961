#include "sim_core/solver/strain_limit.h"

namespace costume::sim {

namespace {

/// Inverse mass of particle i, 0 when pinned (it must not move).
double InverseMass(const ClothModel& model, int i) {
  return model.is_pinned()[i] ? 0.0 : 1.0 / model.masses()[i];
}

/// Shortens one spring to `max_length` if longer; returns whether it did.
bool Shorten(const ClothModel& model, const Spring& s, double max_length, ClothState& state) {
  const Eigen::Vector3d d = (state.positions.row(s.b) - state.positions.row(s.a)).transpose();
  const double length = d.norm();
  if (length <= max_length) return false;
  const double wa = InverseMass(model, s.a), wb = InverseMass(model, s.b);
  if (wa + wb == 0.0) return false;
  const Eigen::Vector3d u = d / length;
  const Eigen::Vector3d correction = (length - max_length) / (wa + wb) * u;
  state.positions.row(s.a) += wa * correction.transpose();
  state.positions.row(s.b) -= wb * correction.transpose();
  // Like an inelastic collision: the ends stop separating along the spring. Provot instead
  // adds correction/h to the velocities, which can pump energy into stiff cloth.
  const double separating =
      (state.velocities.row(s.b) - state.velocities.row(s.a)).dot(u.transpose());
  if (separating > 0.0) {
    const Eigen::Vector3d impulse = separating / (wa + wb) * u;  // per unit inverse mass
    state.velocities.row(s.a) += wa * impulse.transpose();
    state.velocities.row(s.b) -= wb * impulse.transpose();
  }
  return true;
}

}  // namespace

int LimitStrain(const ClothModel& model, double limit, int passes, ClothState& state) {
  int corrections = 0;
  for (int pass = 0; pass < passes; ++pass) {
    int this_pass = 0;
    for (const Spring& s : model.springs()) {
      if (s.kind == SpringKind::kBending) continue;  // bending springs may stretch when folding
      this_pass += Shorten(model, s, (1.0 + limit) * s.rest_length, state) ? 1 : 0;
    }
    corrections += this_pass;
    if (this_pass == 0) break;
  }
  return corrections;
}

}  // namespace costume::sim
