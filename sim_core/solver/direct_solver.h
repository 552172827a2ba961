#pragma once
/// @file
/// The same filtered implicit step solved exactly by sparse Cholesky (CHOLMOD, supernodal):
/// the accuracy reference for the iterative solvers.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>

#include "sim_core/solver/constraints.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

class DirectSolver {
 public:
  /// Analyses the sparsity pattern of `a` once (ordering and symbolic factorisation).
  explicit DirectSolver(const SystemMatrix& a);
  ~DirectSolver();

  /// Solves S A S y + (I − S) y = S (b − A z), dv = z + y, with z = constraints.prescribed():
  /// the exact solution of the system PCG iterates on. Returns false (dv untouched) when the
  /// factorisation fails (matrix not positive definite). Never throws.
  bool Solve(const SystemMatrix& a, const Eigen::VectorXd& b, const Constraints& constraints,
             Eigen::VectorXd& dv);

  /// The two halves of Solve, for solving one factorisation many times (the multigrid's
  /// coarsest level): factorises S A S + (I − S); false when that fails. CHOLMOD's numeric
  /// factorisation allocates its workspace on every call.
  bool Factorize(const SystemMatrix& a, const Constraints& constraints);
  /// y = (S A S + (I − S))⁻¹ rhs with the last factorisation; rhs must be filtered (S rhs).
  /// Never allocates after the first call (y sized, CHOLMOD's workspaces kept); a failed
  /// solve leaves y NaN.
  void SolveFactored(const Eigen::VectorXd& rhs, Eigen::VectorXd& y);

  /// CHOLMOD's state, opaque outside direct_solver.cc.
  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace costume::sim
