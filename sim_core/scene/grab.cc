#include "sim_core/scene/grab.h"

#include <cmath>

#include "sim_core/solver/spring_forces.h"

namespace costume::sim {

bool IsValidGrab(const Grab& grab) {
  return grab.centre.allFinite() && grab.force.allFinite() && std::isfinite(grab.radius) &&
         grab.radius > 0.0 && std::isfinite(grab.coupling_stiffness) &&
         grab.coupling_stiffness >= 0.0;
}

double GaussianWeight(const Eigen::Vector3d& x, const Eigen::Vector3d& centre, double variance) {
  return std::exp(-(x - centre).squaredNorm() / (2.0 * variance));
}

double GrabWeight(const Grab& grab, const Eigen::Vector3d& x) {
  return GaussianWeight(x, grab.centre, GaussianVariance(grab.radius));
}

void SelectWithin(const Points& positions, const Eigen::Vector3d& centre, double radius,
                  std::vector<int>& selected) {
  selected.clear();
  const double r2 = radius * radius;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    if ((positions.row(i).transpose() - centre).squaredNorm() <= r2) {
      selected.push_back(static_cast<int>(i));
    }
  }
}

void SelectGrabbed(const Grab& grab, const Points& positions, std::vector<int>& selected) {
  SelectWithin(positions, grab.centre, grab.radius, selected);
}

void ApplyGrab(const Grab& grab, const Points& positions, const std::vector<int>& selected,
               Points& applied) {
  applied.setZero(positions.rows(), 3);
  for (int i : selected) {
    applied.row(i) = (GrabWeight(grab, positions.row(i).transpose()) * grab.force).transpose();
  }
}

Eigen::Vector3d GrabFeedback(const ClothModel& model, const ClothState& state,
                             const std::vector<int>& selected, std::vector<char>& is_selected) {
  is_selected.assign(model.num_particles(), 0);
  for (int p : selected) is_selected[p] = 1;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Spring& s : model.springs()) {
    if (is_selected[s.a] == is_selected[s.b]) continue;  // outside, or internal: cancels
    const SpringTerms t = EvaluateSpring(
        s, state.positions.row(s.a).transpose(), state.positions.row(s.b).transpose(),
        state.velocities.row(s.a).transpose(), state.velocities.row(s.b).transpose(),
        JacobianMode::kDefinite);
    sum += is_selected[s.a] ? t.force_on_a : Eigen::Vector3d(-t.force_on_a);
  }
  return sum;
}

}  // namespace costume::sim
