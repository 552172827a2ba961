#pragma once
/// @file
/// The modified preconditioned conjugate gradient of Baraff & Witkin 1998 §5.3: solves
/// A Δv = b on the free directions while the constrained directions hold their prescribed
/// values exactly throughout the iteration. The preconditioner is pluggable: block Jacobi
/// (the inverse 3×3 diagonal blocks, B&W's scalar diagonal being its special case) or the
/// multigrid V-cycle of sim_core/hierarchy.

#include <Eigen/Core>
#include <vector>

#include "sim_core/common/thread_pool.h"
#include "sim_core/solver/constraints.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

struct PcgSettings {
  /// Stop when ‖S(b − AΔv)‖ < tolerance · ‖Sb‖ and rᵀP⁻¹r < tolerance² · (Sb)ᵀP⁻¹(Sb)
  /// [-] (see the .cc for why both).
  double tolerance = 1e-2;
  int max_iterations = 1000;
  /// Threads the solve's loops run on (held by the caller); null: the caller's thread alone.
  /// The result is the same bits either way (thread_pool.h).
  ThreadPool* pool = nullptr;
};

struct PcgReport {
  int iterations = 0;
  /// ‖S(b − AΔv)‖ / ‖Sb‖ at exit [-].
  double relative_residual = 0.0;
  bool converged = false;
};

/// An approximation M⁻¹ of A⁻¹ for PCG; must be symmetric positive definite on the free
/// directions.
class PcgPreconditioner {
 public:
  virtual ~PcgPreconditioner() = default;
  /// Prepares for systems with matrix `a` under `constraints`. Never allocates.
  virtual void Update(const SystemMatrix& a, const Constraints& constraints) = 0;
  /// z = M⁻¹ r (3n vectors). Never allocates.
  virtual void Apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) = 0;
};

/// M = the 3×3 diagonal blocks of A.
class BlockJacobiPreconditioner : public PcgPreconditioner {
 public:
  /// `pool` (held by the caller, may be null) spreads Update and Apply over its threads.
  explicit BlockJacobiPreconditioner(int num_particles, ThreadPool* pool = nullptr)
      : inverse_diagonal_(num_particles), pool_(pool) {}
  void Update(const SystemMatrix& a, const Constraints& constraints) override;
  void Apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) override;
  const std::vector<Eigen::Matrix3d>& inverse_diagonal() const { return inverse_diagonal_; }

 private:
  std::vector<Eigen::Matrix3d> inverse_diagonal_;
  ThreadPool* pool_;
};

/// x · y over 3n vectors, summed chunk by chunk (thread_pool.h: the same bits with or
/// without `pool`); `partial` holds ThreadPool::NumChunks(n) values. Never allocates.
double ChunkedDot(ThreadPool* pool, const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                  std::vector<double>& partial);

class FilteredPcg {
 public:
  /// Allocates the workspace for `num_particles`.
  explicit FilteredPcg(int num_particles);

  /// Solves with initial guess `dv` (3n, in/out): on return S(A dv − b) ≈ 0 and
  /// (I − S) dv = constraints.prescribed(). `preconditioner` must have been updated for
  /// `a` and `constraints`. Never allocates; never throws.
  PcgReport Solve(const SystemMatrix& a, const Eigen::VectorXd& b,
                  const Constraints& constraints, const PcgSettings& settings,
                  PcgPreconditioner& preconditioner, Eigen::VectorXd& dv);

 private:
  Eigen::VectorXd r_, c_, q_, s_;
  std::vector<double> partial_;  // one per chunk of particles: the dot products' parts
};

}  // namespace costume::sim
