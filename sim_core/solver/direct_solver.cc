#include "sim_core/solver/direct_solver.h"

#include <Eigen/CholmodSupport>
#include <vector>

namespace costume::sim {

struct DirectSolver::Impl {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> cholesky;
  /// The filtered matrix in CHOLMOD's compressed-column form, same pattern as A.
  Eigen::SparseMatrix<double> filtered;
  /// For block b and entry r·3 + c: its index in filtered's value array.
  std::vector<int> value_index;
  Eigen::VectorXd rhs, az, y;
};

namespace {

/// The 3×3 filter S_i of particle i.
Eigen::Matrix3d FilterBlock(const Constraints& constraints, int i) {
  switch (constraints.num_constrained_directions(i)) {
    case 0: return Eigen::Matrix3d::Identity();
    case 3: return Eigen::Matrix3d::Zero();
    default: {
      const Eigen::Vector3d& n = constraints.normal(i);
      return Eigen::Matrix3d::Identity() - n * n.transpose();
    }
  }
}

/// Builds the scalar pattern of A and where each block entry lands in it.
void BuildPattern(const SystemMatrix& a, DirectSolver::Impl& m);

}  // namespace

DirectSolver::DirectSolver(const SystemMatrix& a) : impl_(std::make_unique<Impl>()) {
  BuildPattern(a, *impl_);
  impl_->cholesky.analyzePattern(impl_->filtered);
}

DirectSolver::~DirectSolver() = default;

namespace {

void BuildPattern(const SystemMatrix& a, DirectSolver::Impl& m) {
  const int n3 = 3 * a.num_particles();
  std::vector<Eigen::Triplet<double>> triplets;
  for (int i = 0; i < a.num_particles(); ++i) {
    for (int b = a.row_start()[i]; b < a.row_start()[i + 1]; ++b) {
      for (int e = 0; e < 9; ++e) {
        triplets.emplace_back(3 * i + e / 3, 3 * a.block_col()[b] + e % 3, 0.0);
      }
    }
  }
  m.filtered.resize(n3, n3);
  m.filtered.setFromTriplets(triplets.begin(), triplets.end());
  m.filtered.makeCompressed();
  m.value_index.resize(9 * a.num_blocks());
  for (int i = 0; i < a.num_particles(); ++i) {
    for (int b = a.row_start()[i]; b < a.row_start()[i + 1]; ++b) {
      for (int e = 0; e < 9; ++e) {
        const int row = 3 * i + e / 3, col = 3 * a.block_col()[b] + e % 3;
        const int* first = m.filtered.innerIndexPtr() + m.filtered.outerIndexPtr()[col];
        const int* last = m.filtered.innerIndexPtr() + m.filtered.outerIndexPtr()[col + 1];
        m.value_index[9 * b + e] =
            static_cast<int>(std::lower_bound(first, last, row) - m.filtered.innerIndexPtr());
      }
    }
  }
}

/// Copies A into the CSC matrix, replacing every block touching a constrained particle by
/// S_i A_ij S_j (+ I − S_i on the diagonal): same pattern, SPD, constrained directions
/// decoupled.
void CopyFiltered(const SystemMatrix& a, const Constraints& constraints,
                  DirectSolver::Impl& m) {
  double* values = m.filtered.valuePtr();
  for (int i = 0; i < a.num_particles(); ++i) {
    const bool row_free = constraints.num_constrained_directions(i) == 0;
    for (int b = a.row_start()[i]; b < a.row_start()[i + 1]; ++b) {
      const int j = a.block_col()[b];
      Eigen::Matrix3d block = a.block(b);
      if (!row_free || constraints.num_constrained_directions(j) != 0) {
        const Eigen::Matrix3d si = FilterBlock(constraints, i);
        block = si * block * FilterBlock(constraints, j);
        if (i == j) block += Eigen::Matrix3d::Identity() - si;
      }
      for (int e = 0; e < 9; ++e) values[m.value_index[9 * b + e]] = block(e / 3, e % 3);
    }
  }
}

}  // namespace

bool DirectSolver::Factorize(const SystemMatrix& a, const Constraints& constraints) {
  CopyFiltered(a, constraints, *impl_);
  impl_->cholesky.factorize(impl_->filtered);
  return impl_->cholesky.info() == Eigen::Success;
}

void DirectSolver::SolveFactored(const Eigen::VectorXd& rhs, Eigen::VectorXd& y) {
  y = impl_->cholesky.solve(rhs);
}

bool DirectSolver::Solve(const SystemMatrix& a, const Eigen::VectorXd& b,
                         const Constraints& constraints, Eigen::VectorXd& dv) {
  Impl& m = *impl_;
  if (!Factorize(a, constraints)) return false;
  m.az.resize(b.size());
  a.Multiply(constraints.prescribed(), m.az);
  m.rhs = b - m.az;
  constraints.Filter(m.rhs);
  SolveFactored(m.rhs, m.y);
  if (m.cholesky.info() != Eigen::Success || !m.y.allFinite()) return false;
  dv = m.y + constraints.prescribed();
  return true;
}

}  // namespace costume::sim
