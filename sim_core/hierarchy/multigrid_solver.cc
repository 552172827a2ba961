#include "sim_core/hierarchy/multigrid_solver.h"

namespace costume::sim {

MultigridSolver::MultigridSolver(std::shared_ptr<const QuincunxPyramid> pyramid,
                                 const PcgSettings& settings, JacobianMode mode,
                                 const ExternalForces& external, CoarseOperator coarse)
    : settings_(settings),
      levels_(pyramid, mode, external, coarse, settings.pool),
      fine_(pyramid->level(0).model->num_particles(), settings.pool) {
  if (pyramid->num_levels() > 1) {
    coarsest_ = std::make_unique<DirectSolver>(levels_.level(pyramid->num_levels() - 1).a);
  }
}

MultigridSolver::~MultigridSolver() = default;

SolveReport MultigridSolver::Solve(const ClothState& state, double h, const SystemMatrix& a,
                                   const Eigen::VectorXd& b, const Constraints& constraints,
                                   Eigen::VectorXd& dv) {
  SolveReport report;
  report.solved = Prepare(state, h, a, constraints);
  const PcgReport pcg = fine_.pcg.Solve(a, b, constraints, settings_, *this, dv);
  report.iterations = pcg.iterations;
  report.relative_residual = pcg.relative_residual;
  report.converged = pcg.converged && report.solved;
  return report;
}

bool MultigridSolver::Prepare(const ClothState& state, double h, const SystemMatrix& a,
                              const Constraints& constraints) {
  levels_.Assemble(state, h, a, constraints);
  bool factorized = true;
  if (coarsest_) {
    LevelSystem& top = levels_.level(levels_.num_levels() - 1);
    factorized = coarsest_->Factorize(top.a, top.constraints);
  }
  Update(a, constraints);
  return factorized;
}

void MultigridSolver::Update(const SystemMatrix& a, const Constraints& constraints) {
  fine_a_ = &a;
  fine_constraints_ = &constraints;
  fine_.jacobi.Update(a, constraints);
}

void MultigridSolver::Apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) { Cycle(0, r, z); }

void MultigridSolver::Cycle(int l, const Eigen::VectorXd& r, Eigen::VectorXd& z) {
  const bool fine = l == 0;
  const SystemMatrix& a = fine ? *fine_a_ : levels_.level(l).a;
  const Constraints& constraints = fine ? *fine_constraints_ : levels_.level(l).constraints;
  BlockJacobiPreconditioner& jacobi = fine ? fine_.jacobi : levels_.level(l).jacobi;
  Eigen::VectorXd& residual = fine ? fine_.residual : levels_.level(l).r;
  Eigen::VectorXd& scratch = fine ? fine_.scratch : levels_.level(l).t;
  if (l == levels_.num_levels() - 1 && coarsest_) {
    residual = r;
    constraints.Filter(residual);
    coarsest_->SolveFactored(residual, z);
    return;
  }
  // Pre-smoothing from z = 0: the first damped block-Jacobi sweep needs no product.
  jacobi.Apply(r, z);
  constraints.Filter(z);
  z *= kOmega;
  SmoothJacobi(a, r, constraints, jacobi, kSweeps - 1, z, residual, scratch, settings_.pool);
  if (l + 1 < levels_.num_levels()) {
    // Coarse correction of the smoothed residual.
    a.Multiply(z, scratch, settings_.pool);
    residual = r - scratch;
    constraints.Filter(residual);
    LevelSystem& coarse = levels_.level(l + 1);
    levels_.pyramid().Restrict(l + 1, residual, coarse.b, settings_.pool);
    coarse.constraints.Filter(coarse.b);
    Cycle(l + 1, coarse.b, coarse.x);
    levels_.pyramid().Prolongate(l + 1, coarse.x, scratch, settings_.pool);
    constraints.Filter(scratch);
    z += scratch;
  }
  SmoothJacobi(a, r, constraints, jacobi, kSweeps, z, residual, scratch, settings_.pool);
}

}  // namespace costume::sim
