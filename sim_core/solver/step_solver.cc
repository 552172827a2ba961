#include "sim_core/solver/step_solver.h"

namespace costume::sim {

SolveReport FlatPcgSolver::Solve(const ClothState&, double, const SystemMatrix& a,
                                 const Eigen::VectorXd& b, const Constraints& constraints,
                                 Eigen::VectorXd& dv) {
  jacobi_.Update(a, constraints);
  const PcgReport pcg = pcg_.Solve(a, b, constraints, settings_, jacobi_, dv);
  SolveReport report;
  report.iterations = pcg.iterations;
  report.relative_residual = pcg.relative_residual;
  report.converged = pcg.converged;
  return report;
}

SolveReport DirectStepSolver::Solve(const ClothState&, double, const SystemMatrix& a,
                                    const Eigen::VectorXd& b, const Constraints& constraints,
                                    Eigen::VectorXd& dv) {
  SolveReport report;
  report.solved = direct_.Solve(a, b, constraints, dv);
  report.converged = report.solved;
  return report;
}

}  // namespace costume::sim
