#pragma once
/// @file
/// Strategies for solving one implicit step's filtered system A Δv = b: flat PCG, CHOLMOD,
/// and (in sim_core/hierarchy) the paper's hierarchical step and multigrid PCG. The stepper
/// assembles level 0; a strategy may look at the state to build coarser levels.

#include <Eigen/Core>
#include <memory>

#include "sim_core/cloth/cloth_state.h"
#include "sim_core/solver/constraints.h"
#include "sim_core/solver/direct_solver.h"
#include "sim_core/solver/filtered_pcg.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

/// How one solve went.
struct SolveReport {
  /// Iterations of the level-0 solve (the coarse levels' are in coarse_iterations).
  int iterations = 0;
  /// Iterations spent on coarser levels (hierarchical step), 0 otherwise.
  int coarse_iterations = 0;
  double relative_residual = 0.0;
  bool converged = true;
  /// False when the solve failed outright (factorisation of a non-SPD matrix).
  bool solved = true;
};

class StepSolver {
 public:
  virtual ~StepSolver() = default;
  /// Solves the system assembled at (`state`, h) for `dv` (3n; in: the previous step's Δv,
  /// a warm start; out: the solution). Never throws; never allocates after the first call.
  virtual SolveReport Solve(const ClothState& state, double h, const SystemMatrix& a,
                            const Eigen::VectorXd& b, const Constraints& constraints,
                            Eigen::VectorXd& dv) = 0;
};

/// Flat filtered PCG with the block-Jacobi preconditioner, warm-started.
class FlatPcgSolver : public StepSolver {
 public:
  FlatPcgSolver(int num_particles, const PcgSettings& settings)
      : settings_(settings), pcg_(num_particles), jacobi_(num_particles, settings.pool) {}
  SolveReport Solve(const ClothState& state, double h, const SystemMatrix& a,
                    const Eigen::VectorXd& b, const Constraints& constraints,
                    Eigen::VectorXd& dv) override;

 private:
  PcgSettings settings_;
  FilteredPcg pcg_;
  BlockJacobiPreconditioner jacobi_;
};

/// CHOLMOD: the exact solution of the filtered system.
class DirectStepSolver : public StepSolver {
 public:
  /// Analyses the sparsity of `model`'s system once.
  explicit DirectStepSolver(const ClothModel& model) : direct_(SystemMatrix(model)) {}
  SolveReport Solve(const ClothState& state, double h, const SystemMatrix& a,
                    const Eigen::VectorXd& b, const Constraints& constraints,
                    Eigen::VectorXd& dv) override;

 private:
  DirectSolver direct_;
};

}  // namespace costume::sim
