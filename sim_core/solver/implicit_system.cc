#include "sim_core/solver/implicit_system.h"

namespace costume::sim {

void AssembleImplicitSystem(const ClothModel& model, const ClothState& state, double h,
                            JacobianMode mode, const ExternalForces& external, SystemMatrix& a,
                            Eigen::VectorXd& b) {
  a.SetZero();
  for (int i = 0; i < model.num_particles(); ++i) {
    const double drag = external.air_drag ? model.drag()[i] : 0.0;
    a.AddToDiagonal(i, (model.masses()[i] + h * drag) * Eigen::Matrix3d::Identity());
    const Eigen::Vector3d v = state.velocities.row(i).transpose();
    b.segment<3>(3 * i) = h * (model.masses()[i] * external.gravity - drag * v);
    if (external.applied) b.segment<3>(3 * i) += h * external.applied->row(i).transpose();
  }
  const auto& springs = model.springs();
  for (int k = 0; k < model.num_springs(); ++k) {
    const Spring& s = springs[k];
    const Eigen::Vector3d va = state.velocities.row(s.a).transpose();
    const Eigen::Vector3d vb = state.velocities.row(s.b).transpose();
    const SpringTerms t = EvaluateSpring(s, state.positions.row(s.a).transpose(),
                                         state.positions.row(s.b).transpose(), va, vb, mode);
    a.AddSpringCoupling(k, h * t.df_dv + (h * h) * t.df_dx);
    const Eigen::Vector3d rhs = h * (t.force_on_a + h * (t.df_dx * (vb - va)));
    b.segment<3>(3 * s.a) += rhs;
    b.segment<3>(3 * s.b) -= rhs;
  }
}

}  // namespace costume::sim
