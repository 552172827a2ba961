#include "sim_core/solver/direct_solver.h"

#include <Eigen/CholmodSupport>

namespace costume::sim {

struct DirectSolver::Impl {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> cholesky;
  Eigen::SparseMatrix<double> filtered;
  Eigen::VectorXd rhs, az, y;
};

DirectSolver::DirectSolver(const SystemMatrix& a) : impl_(std::make_unique<Impl>()) {
  impl_->filtered = a.matrix();
  impl_->cholesky.analyzePattern(impl_->filtered);
}

DirectSolver::~DirectSolver() = default;

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

/// Replaces every block touching a constrained particle by S_i A_ij S_j (+ I − S_i on the
/// diagonal), which keeps the pattern and makes the matrix SPD with the constrained
/// directions decoupled.
void FilterMatrix(const SystemMatrix& a, const Constraints& constraints, double* values) {
  a.ForEachBlock([&](int i, int j, int offset, int stride) {
    if (constraints.num_constrained_directions(i) == 0 &&
        constraints.num_constrained_directions(j) == 0) {
      return;
    }
    Eigen::Matrix3d block;
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) block(r, c) = values[offset + c * stride + r];
    }
    const Eigen::Matrix3d si = FilterBlock(constraints, i);
    block = si * block * FilterBlock(constraints, j);
    if (i == j) block += Eigen::Matrix3d::Identity() - si;
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) values[offset + c * stride + r] = block(r, c);
    }
  });
}

}  // namespace

bool DirectSolver::Solve(const SystemMatrix& a, const Eigen::VectorXd& b,
                         const Constraints& constraints, Eigen::VectorXd& dv) {
  Impl& m = *impl_;
  std::copy_n(a.matrix().valuePtr(), a.matrix().nonZeros(), m.filtered.valuePtr());
  FilterMatrix(a, constraints, m.filtered.valuePtr());
  m.cholesky.factorize(m.filtered);
  if (m.cholesky.info() != Eigen::Success) return false;
  a.Multiply(constraints.prescribed(), m.az);
  m.rhs = b - m.az;
  constraints.Filter(m.rhs);
  m.y = m.cholesky.solve(m.rhs);
  if (m.cholesky.info() != Eigen::Success) return false;
  dv = m.y + constraints.prescribed();
  return true;
}

}  // namespace costume::sim
