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
    if (external.anchor_stiffness && (*external.anchor_stiffness)[i] > 0.0) {
      // f = k (target − x), ∂f/∂x = −k I: A += h² k I, b += h (f − h k v) (B&W eq. 6).
      const double k = (*external.anchor_stiffness)[i];
      const Eigen::Vector3d x = state.positions.row(i).transpose();
      a.AddToDiagonal(i, (h * h * k) * Eigen::Matrix3d::Identity());
      b.segment<3>(3 * i) += h * (k * (external.anchor_targets->row(i).transpose() - x) - h * k * v);
    }
  }
  const auto& springs = model.springs();
  for (int k = 0; k < model.num_springs(); ++k) {
    const Spring& s = springs[k];
    const Eigen::Vector3d va = state.velocities.row(s.a).transpose();
    const Eigen::Vector3d vb = state.velocities.row(s.b).transpose();
    const SpringTerms t = EvaluateSpring(s, state.positions.row(s.a).transpose(),
                                         state.positions.row(s.b).transpose(), va, vb, mode);
    // h ∂f/∂v + h² ∂f/∂x = h²k_t I + (h c + h²(k_a − k_t)) d̂d̂ᵀ.
    a.AddSpringCoupling(k, h * h * t.transverse_stiffness,
                        h * t.damping + h * h * (t.axial_stiffness - t.transverse_stiffness),
                        t.direction);
    const Eigen::Vector3d rhs = h * (t.force_on_a + h * t.DfDxTimes(vb - va));
    b.segment<3>(3 * s.a) += rhs;
    b.segment<3>(3 * s.b) -= rhs;
  }
}

}  // namespace costume::sim
