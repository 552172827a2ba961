#pragma once
/// @file
/// The implicit-step systems of the pyramid's coarse levels, assembled from the restricted
/// level-0 state: what the hierarchical step solves and what the multigrid V-cycle uses as
/// coarse-grid operators.

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/solver/filtered_pcg.h"
#include "sim_core/solver/spring_forces.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

/// One level's system and scratch vectors (all 3·n_l long).
struct LevelSystem {
  explicit LevelSystem(const ClothModel& model);
  SystemMatrix a;
  Eigen::VectorXd b;
  Constraints constraints;
  ClothState state;
  BlockJacobiPreconditioner jacobi;
  FilteredPcg pcg;
  Eigen::VectorXd x, r, t;
};

/// Level 0's scratch for the pyramid's solvers (its system is the stepper's).
struct FineWorkspace {
  explicit FineWorkspace(int num_particles)
      : pcg(num_particles),
        jacobi(num_particles),
        residual(3 * num_particles),
        scratch(3 * num_particles) {}
  FilteredPcg pcg;
  BlockJacobiPreconditioner jacobi;
  Eigen::VectorXd residual, scratch;
};

class LevelSystems {
 public:
  /// Allocates the systems of levels 1 .. pyramid.num_levels() − 1.
  LevelSystems(std::shared_ptr<const QuincunxPyramid> pyramid, JacobianMode mode,
               const ExternalForces& external);

  /// Assembles every coarse level at the restriction of `level0` for step h [s], with the
  /// level-0 constraints restricted (pins and contacts of kept particles). Never allocates.
  void Assemble(const ClothState& level0, double h, const Constraints& level0_constraints);

  int num_levels() const { return pyramid_->num_levels(); }
  /// Level l >= 1.
  LevelSystem& level(int l) { return *levels_[l]; }
  const QuincunxPyramid& pyramid() const { return *pyramid_; }

 private:
  std::shared_ptr<const QuincunxPyramid> pyramid_;
  JacobianMode mode_;
  ExternalForces external_;
  std::vector<std::unique_ptr<LevelSystem>> levels_;  // [0] unused: level 0 is the stepper's
};

/// ω = 2/3: the classic damping that makes Jacobi a smoother for Laplacian-like operators.
constexpr double kJacobiDamping = 2.0 / 3.0;

/// `sweeps` damped block-Jacobi sweeps on A x = b from the current x, filtered; `jacobi`
/// must be updated for `a`. `t` is scratch. Never allocates. (The hierarchical step's
/// filter between levels.)
void SmoothJacobi(const SystemMatrix& a, const Eigen::VectorXd& b, const Constraints& constraints,
                  BlockJacobiPreconditioner& jacobi, int sweeps, Eigen::VectorXd& x,
                  Eigen::VectorXd& r, Eigen::VectorXd& t);

}  // namespace costume::sim
