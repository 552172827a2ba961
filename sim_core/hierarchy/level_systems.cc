#include "sim_core/hierarchy/level_systems.h"

#include "sim_core/solver/implicit_system.h"

namespace costume::sim {

LevelSystem::LevelSystem(const ClothModel& model)
    : a(model),
      b(Eigen::VectorXd::Zero(3 * model.num_particles())),
      constraints(model.num_particles()),
      state(ClothState::AtRest(model)),
      jacobi(model.num_particles()),
      pcg(model.num_particles()),
      x(Eigen::VectorXd::Zero(3 * model.num_particles())),
      r(Eigen::VectorXd::Zero(3 * model.num_particles())),
      t(Eigen::VectorXd::Zero(3 * model.num_particles())) {}

LevelSystems::LevelSystems(std::shared_ptr<const QuincunxPyramid> pyramid, JacobianMode mode,
                           const ExternalForces& external)
    : pyramid_(std::move(pyramid)), mode_(mode), external_(external) {
  levels_.resize(pyramid_->num_levels());
  for (int l = 1; l < pyramid_->num_levels(); ++l) {
    levels_[l] = std::make_unique<LevelSystem>(*pyramid_->level(l).model);
  }
}

void LevelSystems::Assemble(const ClothState& level0, double h,
                            const Constraints& level0_constraints) {
  for (int l = 1; l < num_levels(); ++l) {
    LevelSystem& system = *levels_[l];
    const ClothModel& model = *pyramid_->level(l).model;
    pyramid_->RestrictState(l, level0, system.state);
    AssembleImplicitSystem(model, system.state, h, mode_, external_, system.a, system.b);
    pyramid_->RestrictConstraints(l, level0_constraints, system.constraints);
    system.jacobi.Update(system.a, system.constraints);
  }
}

void SmoothJacobi(const SystemMatrix& a, const Eigen::VectorXd& b, const Constraints& constraints,
                  BlockJacobiPreconditioner& jacobi, int sweeps, Eigen::VectorXd& x,
                  Eigen::VectorXd& r, Eigen::VectorXd& t) {
  constexpr double kOmega = kJacobiDamping;
  for (int s = 0; s < sweeps; ++s) {
    a.Multiply(x, t);
    r = b - t;
    constraints.Filter(r);
    jacobi.Apply(r, t);
    constraints.Filter(t);
    x.noalias() += kOmega * t;
  }
}

}  // namespace costume::sim
