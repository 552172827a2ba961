#include "sim_core/solver/implicit_system.h"

namespace costume::sim {

namespace {

/// Particle i's own terms: its diagonal block (mass, drag, anchor) and its b (gravity, drag,
/// applied force, anchor), before any spring's.
void AssembleParticle(const ClothModel& model, const ClothState& state, double h,
                      const ExternalForces& external, int i, SystemMatrix& a, Eigen::VectorXd& b) {
  const double drag = external.air_drag ? model.drag()[i] : 0.0;
  double* d = a.diagonal_values() + 9 * static_cast<std::size_t>(i);
  const double own = model.masses()[i] + h * drag;
  for (int e = 0; e < 9; ++e) d[e] = e % 4 == 0 ? own : 0.0;
  const Eigen::Vector3d v = state.velocities.row(i).transpose();
  b.segment<3>(3 * i) = h * (model.masses()[i] * external.gravity - drag * v);
  if (external.applied) b.segment<3>(3 * i) += h * external.applied->row(i).transpose();
  if (external.anchor_stiffness && (*external.anchor_stiffness)[i] > 0.0) {
    // f = k (target − x), ∂f/∂x = −k I: A += h² k I, b += h (f − h k v) (B&W eq. 6).
    const double k = (*external.anchor_stiffness)[i];
    const Eigen::Vector3d x = state.positions.row(i).transpose();
    for (int e = 0; e < 9; e += 4) d[e] += h * h * k;
    b.segment<3>(3 * i) += h * (k * (external.anchor_targets->row(i).transpose() - x) - h * k * v);
  }
}

/// Spring k's coupling block and its share of b (+ on its first particle, − on its second).
void AssembleSpring(const ClothModel& model, const ClothState& state, double h, JacobianMode mode,
                    int k, SystemMatrix& a, Eigen::VectorXd& spring_rhs) {
  const Spring& s = model.springs()[k];
  const Eigen::Vector3d va = state.velocities.row(s.a).transpose();
  const Eigen::Vector3d vb = state.velocities.row(s.b).transpose();
  const SpringTerms t = EvaluateSpring(s, state.positions.row(s.a).transpose(),
                                       state.positions.row(s.b).transpose(), va, vb, mode);
  // h ∂f/∂v + h² ∂f/∂x = h²k_t I + (h c + h²(k_a − k_t)) d̂d̂ᵀ.
  a.SetSpringCoupling(k, h * h * t.transverse_stiffness,
                      h * t.damping + h * h * (t.axial_stiffness - t.transverse_stiffness),
                      t.direction);
  spring_rhs.segment<3>(3 * k) = h * (t.force_on_a + h * t.DfDxTimes(vb - va));
}

}  // namespace

void AssembleImplicitSystem(const ClothModel& model, const ClothState& state, double h,
                            JacobianMode mode, const ExternalForces& external, SystemMatrix& a,
                            Eigen::VectorXd& b, Eigen::VectorXd& spring_rhs, ThreadPool* pool) {
  const int n = model.num_particles();
  ForEachParticleChunk(pool, n, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) AssembleParticle(model, state, h, external, i, a, b);
  });
  // Springs in chunks of the same size (a chunk's work is alike whatever indexes it).
  ForEachParticleChunk(pool, model.num_springs(), [&](int begin, int end) {
    for (int k = begin; k < end; ++k) AssembleSpring(model, state, h, mode, k, a, spring_rhs);
  });
  ForEachParticleChunk(pool, n, [&](int begin, int end) {
    a.AddCouplingsToDiagonals(begin, end);
    a.AddSpringVectors(begin, end, spring_rhs, b);
  });
}

void AssembleImplicitSystem(const ClothModel& model, const ClothState& state, double h,
                            JacobianMode mode, const ExternalForces& external, SystemMatrix& a,
                            Eigen::VectorXd& b) {
  Eigen::VectorXd spring_rhs(3 * model.num_springs());
  AssembleImplicitSystem(model, state, h, mode, external, a, b, spring_rhs, nullptr);
}

}  // namespace costume::sim
