#include "sim_core/hierarchy/hierarchical_solver.h"

#include <vector>

namespace costume::sim {

HierarchicalSolver::HierarchicalSolver(std::shared_ptr<const QuincunxPyramid> pyramid,
                                       const PcgSettings& settings, JacobianMode mode,
                                       const ExternalForces& external)
    : settings_(settings),
      levels_(pyramid, mode, external, CoarseOperator::kRediscretised, settings.pool),
      fine_(pyramid->level(0).model->num_particles(), settings.pool) {}

SolveReport HierarchicalSolver::Solve(const ClothState& state, double h, const SystemMatrix& a,
                                      const Eigen::VectorXd& b, const Constraints& constraints,
                                      Eigen::VectorXd& dv) {
  SolveReport report;
  const int top = levels_.num_levels() - 1;
  if (top == 0) dv.setZero();  // one level: the flat solve from zero, as the paper's top
  levels_.Assemble(state, h, a, constraints);
  // Figure 5: the top level from zero, each result filtered into the next level's guess.
  for (int l = top; l >= 1; --l) {
    LevelSystem& level = levels_.level(l);
    if (l == top) level.x.setZero();
    const PcgReport coarse =
        level.pcg.Solve(level.a, level.b, level.constraints, settings_, level.jacobi, level.x);
    report.coarse_iterations += coarse.iterations;
    Eigen::VectorXd& finer_guess = l == 1 ? dv : levels_.level(l - 1).x;
    levels_.pyramid().Prolongate(l, level.x, finer_guess, settings_.pool);
    if (l > 1) {
      LevelSystem& finer = levels_.level(l - 1);
      SmoothJacobi(finer.a, finer.b, finer.constraints, finer.jacobi, kSmoothingSweeps, finer.x,
                   finer.r, finer.t, settings_.pool);
    }
  }
  fine_.jacobi.Update(a, constraints);
  if (top > 0) {
    SmoothJacobi(a, b, constraints, fine_.jacobi, kSmoothingSweeps, dv, fine_.residual,
                 fine_.scratch, settings_.pool);
  }
  const PcgReport fine = fine_.pcg.Solve(a, b, constraints, settings_, fine_.jacobi, dv);
  report.iterations = fine.iterations;
  report.relative_residual = fine.relative_residual;
  report.converged = fine.converged;
  return report;
}

}  // namespace costume::sim
