#pragma once
/// @file
/// Beyond the paper: the quincunx pyramid as a multigrid preconditioner. Level-0 filtered
/// PCG, each iteration preconditioned by one V-cycle: damped block-Jacobi smoothing before
/// and after, restriction Pᵀ to the next coarser level's dynamic-equivalent system,
/// prolongation P back, CHOLMOD on the coarsest level. Same sweeps before and after and
/// R = Pᵀ make the V-cycle symmetric, as CG needs.

#include <memory>
#include <vector>

#include "sim_core/hierarchy/level_systems.h"
#include "sim_core/solver/direct_solver.h"
#include "sim_core/solver/step_solver.h"

namespace costume::sim {

class MultigridSolver : public StepSolver, private PcgPreconditioner {
 public:
  /// `pyramid` must have at least one level; with only level 0 this is flat PCG.
  MultigridSolver(std::shared_ptr<const QuincunxPyramid> pyramid, const PcgSettings& settings,
                  JacobianMode mode, const ExternalForces& external);
  ~MultigridSolver() override;

  SolveReport Solve(const ClothState& state, double h, const SystemMatrix& a,
                    const Eigen::VectorXd& b, const Constraints& constraints,
                    Eigen::VectorXd& dv) override;

  /// Damped block-Jacobi sweeps before and after the coarse correction, and their damping.
  static constexpr int kSweeps = 1;
  static constexpr double kOmega = kJacobiDamping;

 private:
  void Update(const SystemMatrix& a, const Constraints& constraints) override;
  void Apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) override;
  /// z_l ≈ A_l⁻¹ r_l by one V-cycle from level l down.
  void Cycle(int l, const Eigen::VectorXd& r, Eigen::VectorXd& z);

  PcgSettings settings_;
  LevelSystems levels_;
  FineWorkspace fine_;
  std::unique_ptr<DirectSolver> coarsest_;
  // Level 0 for the duration of a solve.
  const SystemMatrix* fine_a_ = nullptr;
  const Constraints* fine_constraints_ = nullptr;
};

}  // namespace costume::sim
