#pragma once
/// @file
/// The modified preconditioned conjugate gradient of Baraff & Witkin 1998 §5.3: solves
/// A Δv = b on the free directions while the constrained directions hold their prescribed
/// values exactly throughout the iteration. Preconditioner: the inverse 3×3 diagonal blocks
/// of A (block Jacobi), which B&W's scalar diagonal is the special case of.

#include <Eigen/Core>
#include <vector>

#include "sim_core/solver/constraints.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

struct PcgSettings {
  /// Stop when ‖S(b − AΔv)‖ < tolerance · ‖Sb‖ [-] (see the .cc for why not B&W's
  /// preconditioned norm).
  double tolerance = 1e-2;
  int max_iterations = 1000;
};

struct PcgReport {
  int iterations = 0;
  /// ‖S(b − AΔv)‖ / ‖Sb‖ at exit [-].
  double relative_residual = 0.0;
  bool converged = false;
};

class FilteredPcg {
 public:
  /// Allocates the workspace for `num_particles`.
  explicit FilteredPcg(int num_particles);

  /// Solves with initial guess `dv` (3n, in/out): on return S(A dv − b) ≈ 0 and
  /// (I − S) dv = constraints.prescribed(). Never allocates; never throws.
  PcgReport Solve(const SystemMatrix& a, const Eigen::VectorXd& b,
                  const Constraints& constraints, const PcgSettings& settings,
                  Eigen::VectorXd& dv);

 private:
  void UpdatePreconditioner(const SystemMatrix& a);
  /// out = P⁻¹ in.
  void Precondition(const Eigen::VectorXd& in, Eigen::VectorXd& out) const;

  std::vector<Eigen::Matrix3d> inverse_diagonal_;
  Eigen::VectorXd r_, c_, q_, s_;
};

}  // namespace costume::sim
