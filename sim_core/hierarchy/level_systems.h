#pragma once
/// @file
/// The implicit-step systems of the pyramid's coarse levels: rediscretised (each level's
/// dynamic-equivalent model assembled at the restricted level-0 state: what the
/// hierarchical step solves) or Galerkin products A_{l+1} = P_lᵀ A_l P_l of level 0's
/// matrix (the multigrid V-cycle's alternative; docs/pyramid.md).

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "sim_core/hierarchy/galerkin_operator.h"
#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/solver/filtered_pcg.h"
#include "sim_core/solver/solver_method.h"
#include "sim_core/solver/spring_forces.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

/// One level's system and scratch vectors (all 3·n_l long).
struct LevelSystem {
  /// Matrix `matrix` over model's particles (the model's springs or a Galerkin pattern);
  /// `pool` (may be null) for the smoother's loops.
  LevelSystem(const ClothModel& model, SystemMatrix matrix, ThreadPool* pool = nullptr);
  SystemMatrix a;
  Eigen::VectorXd b;
  Constraints constraints;
  ClothState state;
  BlockJacobiPreconditioner jacobi;
  FilteredPcg pcg;
  Eigen::VectorXd x, r, t;
  /// The rediscretised assembly's scratch (3 per spring of the level's model; empty on a
  /// Galerkin level, which is never assembled).
  Eigen::VectorXd spring_rhs;
};

/// Level 0's scratch for the pyramid's solvers (its system is the stepper's).
struct FineWorkspace {
  explicit FineWorkspace(int num_particles, ThreadPool* pool = nullptr)
      : pcg(num_particles),
        jacobi(num_particles, pool),
        residual(3 * num_particles),
        scratch(3 * num_particles) {}
  FilteredPcg pcg;
  BlockJacobiPreconditioner jacobi;
  Eigen::VectorXd residual, scratch;
};

class LevelSystems {
 public:
  /// Allocates the systems of levels 1 .. pyramid.num_levels() − 1; for kGalerkin also the
  /// products' patterns, level 0's being that of its model's springs. `pool` (may be null)
  /// runs the levels' smoothers on its threads.
  LevelSystems(std::shared_ptr<const QuincunxPyramid> pyramid, JacobianMode mode,
               const ExternalForces& external,
               CoarseOperator coarse = CoarseOperator::kRediscretised, ThreadPool* pool = nullptr);

  /// Sets every coarse level's matrix for step h [s] at level 0's state and matrix
  /// `level0_a` (rediscretised: each coarse model assembled at the restriction of `level0`,
  /// with its right-hand side; Galerkin: P_lᵀ A_l P_l level by level, right-hand sides left
  /// alone), and restricts the level-0 constraints (pins and contacts of kept particles).
  /// Never allocates.
  void Assemble(const ClothState& level0, double h, const SystemMatrix& level0_a,
                const Constraints& level0_constraints);

  int num_levels() const { return pyramid_->num_levels(); }
  /// Level l >= 1.
  LevelSystem& level(int l) { return *levels_[l]; }
  const QuincunxPyramid& pyramid() const { return *pyramid_; }
  /// How the coarse matrices are made.
  CoarseOperator coarse_operator() const { return coarse_; }

 private:
  std::shared_ptr<const QuincunxPyramid> pyramid_;
  JacobianMode mode_;
  ExternalForces external_;
  CoarseOperator coarse_;
  ThreadPool* pool_;
  std::vector<std::unique_ptr<LevelSystem>> levels_;  // [0] unused: level 0 is the stepper's
  std::vector<GalerkinOperator> galerkin_;            // [l − 1] makes level l (kGalerkin)
};

/// ω = 2/3: the classic damping that makes Jacobi a smoother for Laplacian-like operators.
constexpr double kJacobiDamping = 2.0 / 3.0;

/// `sweeps` damped block-Jacobi sweeps on A x = b from the current x, filtered; `jacobi`
/// must be updated for `a`. `t` is scratch; `pool` (may be null) runs the products. Never
/// allocates. (The hierarchical step's filter between levels.)
void SmoothJacobi(const SystemMatrix& a, const Eigen::VectorXd& b, const Constraints& constraints,
                  BlockJacobiPreconditioner& jacobi, int sweeps, Eigen::VectorXd& x,
                  Eigen::VectorXd& r, Eigen::VectorXd& t, ThreadPool* pool = nullptr);

}  // namespace costume::sim
