#pragma once
/// @file
/// The paper's hierarchical step (§3.3, Figures 4–5): the implicit step of the pyramid's top
/// level is solved from a zero initial guess; its result, filtered (prolongation to the next
/// finer level, then damped block-Jacobi smoothing on that level's system), is the initial
/// guess of the next finer level's solve, down to level 0, whose result advances the cloth.
/// Each level solves its own dynamic-equivalent model at the restricted state.

#include <memory>

#include "sim_core/hierarchy/level_systems.h"
#include "sim_core/solver/step_solver.h"

namespace costume::sim {

class HierarchicalSolver : public StepSolver {
 public:
  HierarchicalSolver(std::shared_ptr<const QuincunxPyramid> pyramid, const PcgSettings& settings,
                     JacobianMode mode, const ExternalForces& external);

  SolveReport Solve(const ClothState& state, double h, const SystemMatrix& a,
                    const Eigen::VectorXd& b, const Constraints& constraints,
                    Eigen::VectorXd& dv) override;

  /// Smoothing sweeps of the filter between levels.
  static constexpr int kSmoothingSweeps = 2;

 private:
  PcgSettings settings_;
  LevelSystems levels_;
  FineWorkspace fine_;
};

}  // namespace costume::sim
