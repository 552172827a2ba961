#pragma once
/// @file
/// Which solver an implicit step uses.

namespace costume::sim {

/// How the linear system of each implicit step is solved.
enum class SolverMethod {
  /// Filtered preconditioned conjugate gradient (Baraff & Witkin 1998 §5.3), block-Jacobi
  /// preconditioned: the flat solver.
  kPcg,
  /// The paper's hierarchical step (Figure 5): the quincunx pyramid's top level is solved
  /// from zero, each result filtered into the next finer level's initial guess.
  kHierarchical,
  /// PCG on level 0 preconditioned by a multigrid V-cycle over the same pyramid.
  kMultigrid,
  /// Sparse Cholesky through CHOLMOD: the accuracy reference.
  kDirect,
};

/// "pcg", "hierarchical", "multigrid" or "direct".
const char* SolverMethodName(SolverMethod method);

/// How the multigrid V-cycle gets its coarse-level matrices (docs/pyramid.md).
enum class CoarseOperator {
  /// A_{l+1} = P_lᵀ A_l P_l from level 0's matrix: consistent with it by construction,
  /// whatever the tension (half the iterations on the hanging sheet under load).
  kGalerkin,
  /// Each coarse level's own dynamic-equivalent model assembled at the restricted state
  /// (what the hierarchical step always solves; the default: at the loose default
  /// tolerance the Galerkin cycle left the kicked skirt far more strained).
  kRediscretised,
};

/// Most implicit steps a frame may be split into (a scene's solver.substeps).
constexpr int kMaxSubsteps = 1000;

/// "galerkin" or "rediscretised".
const char* CoarseOperatorName(CoarseOperator coarse);

}  // namespace costume::sim
