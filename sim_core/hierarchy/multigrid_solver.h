#pragma once
/// @file
/// Beyond the paper: the quincunx pyramid as a multigrid preconditioner. Level-0 filtered
/// PCG, each iteration preconditioned by one V-cycle: damped block-Jacobi smoothing before
/// and after, restriction Pᵀ to the next coarser level's dynamic-equivalent system,
/// prolongation P back, CHOLMOD on the coarsest level. The coarse systems are Galerkin
/// products PᵀAP of level 0's matrix or the rediscretised dynamic-equivalent models
/// (default; docs/pyramid.md says why). Same sweeps before and after and
/// R = Pᵀ make the V-cycle symmetric, as CG needs.

#include <memory>
#include <vector>

#include "sim_core/hierarchy/level_systems.h"
#include "sim_core/solver/direct_solver.h"
#include "sim_core/solver/step_solver.h"

namespace costume::sim {

class MultigridSolver : public StepSolver, private PcgPreconditioner {
 public:
  /// `pyramid` must have at least one level; with only level 0 this is flat PCG. `coarse`
  /// picks the coarse levels' matrices (Galerkin products of level 0's or rediscretised).
  MultigridSolver(std::shared_ptr<const QuincunxPyramid> pyramid, const PcgSettings& settings,
                  JacobianMode mode, const ExternalForces& external,
                  CoarseOperator coarse = CoarseOperator::kRediscretised);
  ~MultigridSolver() override;

  SolveReport Solve(const ClothState& state, double h, const SystemMatrix& a,
                    const Eigen::VectorXd& b, const Constraints& constraints,
                    Eigen::VectorXd& dv) override;

  /// Sets up the V-cycle for level-0 matrix `a` (kept by reference until the next call) at
  /// `state` for step h [s] under `constraints`: coarse matrices, restricted constraints,
  /// smoothers, the coarsest factorisation. False when that factorisation failed. Allocates
  /// only inside CHOLMOD's numeric factorisation (its workspace, about ten blocks a call).
  bool Prepare(const ClothState& state, double h, const SystemMatrix& a,
               const Constraints& constraints);
  /// z = M⁻¹ r by one V-cycle (3n vectors, r filtered): the preconditioner PCG applies,
  /// public so its symmetry can be checked. Prepare first. Never allocates.
  void ApplyCycle(const Eigen::VectorXd& r, Eigen::VectorXd& z) { Apply(r, z); }
  /// The coarse levels' systems (level l >= 1), for tests and diagnostics.
  LevelSystems& levels() { return levels_; }

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
