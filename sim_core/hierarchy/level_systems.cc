#include "sim_core/hierarchy/level_systems.h"

#include <utility>

#include "sim_core/solver/implicit_system.h"

namespace costume::sim {

LevelSystem::LevelSystem(const ClothModel& model, SystemMatrix matrix, ThreadPool* pool)
    : a(std::move(matrix)),
      b(Eigen::VectorXd::Zero(3 * model.num_particles())),
      constraints(model.num_particles()),
      state(ClothState::AtRest(model)),
      jacobi(model.num_particles(), pool),
      pcg(model.num_particles()),
      x(Eigen::VectorXd::Zero(3 * model.num_particles())),
      r(Eigen::VectorXd::Zero(3 * model.num_particles())),
      t(Eigen::VectorXd::Zero(3 * model.num_particles())) {}

LevelSystems::LevelSystems(std::shared_ptr<const QuincunxPyramid> pyramid, JacobianMode mode,
                           const ExternalForces& external, CoarseOperator coarse,
                           ThreadPool* pool)
    : pyramid_(std::move(pyramid)), mode_(mode), external_(external), coarse_(coarse), pool_(pool) {
  levels_.resize(pyramid_->num_levels());
  const SystemMatrix level0_pattern(*pyramid_->level(0).model);
  for (int l = 1; l < pyramid_->num_levels(); ++l) {
    const ClothModel& model = *pyramid_->level(l).model;
    if (coarse_ == CoarseOperator::kGalerkin) {
      const SystemMatrix& finer = l == 1 ? level0_pattern : levels_[l - 1]->a;
      galerkin_.emplace_back(finer, pyramid_->level(l), model.num_particles());
      levels_[l] = std::make_unique<LevelSystem>(model, galerkin_.back().MakeCoarseMatrix(), pool_);
    } else {
      levels_[l] = std::make_unique<LevelSystem>(model, SystemMatrix(model), pool_);
      levels_[l]->spring_rhs = Eigen::VectorXd::Zero(3 * model.num_springs());
    }
  }
}

void LevelSystems::Assemble(const ClothState& level0, double h, const SystemMatrix& level0_a,
                            const Constraints& level0_constraints) {
  for (int l = 1; l < num_levels(); ++l) {
    LevelSystem& system = *levels_[l];
    if (coarse_ == CoarseOperator::kGalerkin) {
      galerkin_[l - 1].Compute(l == 1 ? level0_a : levels_[l - 1]->a, system.a, pool_);
    } else {
      const ClothModel& model = *pyramid_->level(l).model;
      pyramid_->RestrictState(l, level0, system.state);
      AssembleImplicitSystem(model, system.state, h, mode_, external_, system.a, system.b,
                             system.spring_rhs, pool_);
    }
    pyramid_->RestrictConstraints(l, level0_constraints, system.constraints);
    system.jacobi.Update(system.a, system.constraints);
  }
}

void SmoothJacobi(const SystemMatrix& a, const Eigen::VectorXd& b, const Constraints& constraints,
                  BlockJacobiPreconditioner& jacobi, int sweeps, Eigen::VectorXd& x,
                  Eigen::VectorXd& r, Eigen::VectorXd& t, ThreadPool* pool) {
  constexpr double kOmega = kJacobiDamping;
  for (int s = 0; s < sweeps; ++s) {
    a.Multiply(x, t, pool);
    r = b - t;
    constraints.Filter(r);
    jacobi.Apply(r, t);
    constraints.Filter(t);
    x.noalias() += kOmega * t;
  }
}

}  // namespace costume::sim
