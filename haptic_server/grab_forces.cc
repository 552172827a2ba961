#include "haptic_server/grab_forces.h"

#include <cmath>

namespace costume::haptics {

void AddGrabForces(const sim::Points& positions, const std::vector<int>& selected,
                   const Eigen::Vector3d& centre, double radius,
                   const Eigen::Vector3d& device_force, sim::Points& forces) {
  const double variance = GaussianVariance(radius);
  for (int i : selected) {
    const double g = GaussianWeight(positions.row(i).transpose(), centre, variance);
    forces.row(i) += g * device_force.transpose();
  }
}

void HapticPatch::Reserve(int num_particles, int num_springs) {
  positions.reserve(num_particles);
  velocities.reserve(num_particles);
  weights.reserve(num_particles);
  springs.reserve(num_springs);
  boundary_springs.reserve(num_springs);
  boundary_signs.reserve(num_springs);
}

namespace {

bool PatchIsFinite(const HapticPatch& patch) {
  const int n = static_cast<int>(patch.positions.size());
  if (patch.velocities.size() != patch.positions.size()) return false;
  if (!patch.centre.allFinite() || !(std::isfinite(patch.radius) && patch.radius > 0)) return false;
  for (int i = 0; i < n; ++i) {
    if (!patch.positions[i].allFinite() || !patch.velocities[i].allFinite()) return false;
  }
  for (const PatchSpring& s : patch.springs) {
    if (s.a < 0 || s.a >= n || s.b < 0 || s.b >= n || s.a == s.b) return false;
    if (!(std::isfinite(s.stiffness) && std::isfinite(s.damping) &&
          std::isfinite(s.rest_length))) {
      return false;
    }
  }
  return true;
}

}  // namespace

void PreparePatch(HapticPatch& patch) {
  patch.weights.clear();
  patch.boundary_springs.clear();
  patch.boundary_signs.clear();
  patch.num_selected = 0;
  patch.valid = PatchIsFinite(patch);
  if (!patch.valid) return;
  const double r2 = patch.radius * patch.radius;
  const double variance = GaussianVariance(patch.radius);
  for (const Eigen::Vector3d& x : patch.positions) {
    const bool inside = (x - patch.centre).squaredNorm() <= r2;
    patch.weights.push_back(inside ? GaussianWeight(x, patch.centre, variance) : 0.0);
    patch.num_selected += inside ? 1 : 0;
  }
  for (int k = 0; k < static_cast<int>(patch.springs.size()); ++k) {
    const bool a_in = patch.weights[patch.springs[k].a] > 0.0;
    const bool b_in = patch.weights[patch.springs[k].b] > 0.0;
    if (a_in == b_in) continue;  // internal springs cancel; outside springs do not touch us
    patch.boundary_springs.push_back(k);
    patch.boundary_signs.push_back(a_in ? 1 : -1);
  }
}

Eigen::Vector3d FeedbackForce(const HapticPatch& patch, const Eigen::Vector3d& tip_displacement) {
  Eigen::Vector3d total = Eigen::Vector3d::Zero();
  if (!patch.valid) return total;
  const std::size_t num_boundary = patch.boundary_springs.size();
  for (std::size_t k = 0; k < num_boundary; ++k) {
    const PatchSpring& s = patch.springs[patch.boundary_springs[k]];
    const Eigen::Vector3d xa = patch.positions[s.a] + patch.weights[s.a] * tip_displacement;
    const Eigen::Vector3d xb = patch.positions[s.b] + patch.weights[s.b] * tip_displacement;
    const Eigen::Vector3d d = xb - xa;
    const double length = d.norm();
    if (length <= 0.0) continue;  // coincident ends: no direction, no force
    const Eigen::Vector3d direction = d / length;
    const double closing_speed = (patch.velocities[s.b] - patch.velocities[s.a]).dot(direction);
    // Force on end a (DESIGN.md eq. 4 plus damping along the spring); end b gets its negative.
    const Eigen::Vector3d on_a =
        (s.stiffness * (length - s.rest_length) + s.damping * closing_speed) * direction;
    total += static_cast<double>(patch.boundary_signs[k]) * on_a;
  }
  return total;
}

}  // namespace costume::haptics
