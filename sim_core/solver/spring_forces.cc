#include "sim_core/solver/spring_forces.h"

#include <cmath>
#include <vector>

namespace costume::sim {

namespace {

Eigen::Vector3d Row(const Points& p, int i) { return p.row(i).transpose(); }

}  // namespace

Eigen::VectorXd ComputeForces(const ClothModel& model, const ClothState& state,
                              const ExternalForces& external) {
  const int n = model.num_particles();
  Eigen::VectorXd f(3 * n);
  for (int i = 0; i < n; ++i) {
    f.segment<3>(3 * i) = model.masses()[i] * external.gravity -
                          (external.air_drag ? model.drag()[i] : 0.0) * Row(state.velocities, i);
    if (external.applied) f.segment<3>(3 * i) += Row(*external.applied, i);
    if (external.anchor_stiffness) {
      f.segment<3>(3 * i) += (*external.anchor_stiffness)[i] *
                             (Row(*external.anchor_targets, i) - Row(state.positions, i));
    }
  }
  for (const Spring& s : model.springs()) {
    const SpringTerms t =
        EvaluateSpring(s, Row(state.positions, s.a), Row(state.positions, s.b),
                       Row(state.velocities, s.a), Row(state.velocities, s.b),
                       JacobianMode::kExact);
    f.segment<3>(3 * s.a) += t.force_on_a;
    f.segment<3>(3 * s.b) -= t.force_on_a;
  }
  return f;
}

namespace {

void AddBlockPattern(std::vector<Eigen::Triplet<double>>& triplets, int a, int b,
                     const Eigen::Matrix3d& block) {
  // Spring blocks: +block at (a, b), (b, a); −block at (a, a), (b, b).
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      triplets.emplace_back(3 * a + r, 3 * b + c, block(r, c));
      triplets.emplace_back(3 * b + r, 3 * a + c, block(r, c));
      triplets.emplace_back(3 * a + r, 3 * a + c, -block(r, c));
      triplets.emplace_back(3 * b + r, 3 * b + c, -block(r, c));
    }
  }
}

}  // namespace

void ComputeForceJacobians(const ClothModel& model, const ClothState& state,
                           const ExternalForces& external, JacobianMode mode,
                           Eigen::SparseMatrix<double>* df_dx,
                           Eigen::SparseMatrix<double>* df_dv) {
  const int n = model.num_particles();
  std::vector<Eigen::Triplet<double>> kx, kv;
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      kv.emplace_back(3 * i + c, 3 * i + c, -(external.air_drag ? model.drag()[i] : 0.0));
      if (external.anchor_stiffness) kx.emplace_back(3 * i + c, 3 * i + c, -(*external.anchor_stiffness)[i]);
    }
  }
  for (const Spring& s : model.springs()) {
    const SpringTerms t =
        EvaluateSpring(s, Row(state.positions, s.a), Row(state.positions, s.b),
                       Row(state.velocities, s.a), Row(state.velocities, s.b), mode);
    AddBlockPattern(kx, s.a, s.b, t.df_dx());
    AddBlockPattern(kv, s.a, s.b, t.df_dv());
  }
  df_dx->resize(3 * n, 3 * n);
  df_dx->setFromTriplets(kx.begin(), kx.end());
  df_dv->resize(3 * n, 3 * n);
  df_dv->setFromTriplets(kv.begin(), kv.end());
}

double MechanicalEnergy(const ClothModel& model, const ClothState& state,
                        const Eigen::Vector3d& gravity) {
  double energy = 0.0;
  for (int i = 0; i < model.num_particles(); ++i) {
    const Eigen::Vector3d x = Row(state.positions, i);
    const Eigen::Vector3d v = Row(state.velocities, i);
    energy += 0.5 * model.masses()[i] * v.squaredNorm() - model.masses()[i] * gravity.dot(x);
  }
  for (const Spring& s : model.springs()) {
    const double stretch =
        (state.positions.row(s.b) - state.positions.row(s.a)).norm() - s.rest_length;
    energy += 0.5 * s.stiffness * stretch * stretch;
  }
  return energy;
}

StrainStats StructuralStrain(const ClothModel& model, const Points& positions) {
  StrainStats stats;
  int count = 0;
  const std::vector<Spring>& springs = model.springs();
  for (std::size_t k = 0; k < springs.size(); ++k) {
    const Spring& s = springs[k];
    if (s.kind != SpringKind::kStructural) continue;
    const double strain = (positions.row(s.b) - positions.row(s.a)).norm() / s.rest_length - 1;
    if (strain > stats.max) {
      stats.max = strain;
      stats.max_spring = static_cast<int>(k);
    }
    stats.mean += std::abs(strain);
    ++count;
  }
  if (count > 0) stats.mean /= count;
  return stats;
}

}  // namespace costume::sim
