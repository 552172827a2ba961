#pragma once
/// @file
/// Which solver an implicit step uses.

namespace costume::sim {

/// How the linear system of each implicit step is solved.
enum class SolverMethod {
  /// Filtered preconditioned conjugate gradient (Baraff & Witkin 1998 §5.3).
  kPcg,
  /// Sparse Cholesky through CHOLMOD: the accuracy reference.
  kDirect,
};

/// "pcg" or "direct".
const char* SolverMethodName(SolverMethod method);

}  // namespace costume::sim
