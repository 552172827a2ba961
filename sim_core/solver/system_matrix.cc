#include "sim_core/solver/system_matrix.h"

#include <algorithm>

namespace costume::sim {

SystemMatrix::SystemMatrix(const ClothModel& model) : num_particles_(model.num_particles()) {
  const int n = num_particles_;
  std::vector<std::vector<int>> neighbours(n);
  for (int i = 0; i < n; ++i) neighbours[i].push_back(i);
  for (const Spring& s : model.springs()) {
    neighbours[s.a].push_back(s.b);
    neighbours[s.b].push_back(s.a);
  }
  for (auto& list : neighbours) std::sort(list.begin(), list.end());

  // Column 3j + c holds, for each neighbour i of j in order, rows 3i..3i+2.
  std::vector<int> column_start(n + 1, 0);
  for (int j = 0; j < n; ++j) column_start[j + 1] = column_start[j] + 9 * neighbours[j].size();
  const int nnz = column_start[n];
  matrix_.resize(3 * n, 3 * n);
  matrix_.resizeNonZeros(nnz);
  int* outer = matrix_.outerIndexPtr();
  int* inner = matrix_.innerIndexPtr();
  stride_.resize(n);
  diagonal_offset_.resize(n);
  for (int j = 0; j < n; ++j) {
    const int degree = static_cast<int>(neighbours[j].size());
    stride_[j] = 3 * degree;
    for (int c = 0; c < 3; ++c) {
      outer[3 * j + c] = column_start[j] + c * stride_[j];
      for (int p = 0; p < degree; ++p) {
        for (int r = 0; r < 3; ++r) inner[outer[3 * j + c] + 3 * p + r] = 3 * neighbours[j][p] + r;
      }
    }
    for (int p = 0; p < degree; ++p) {
      const int offset = column_start[j] + 3 * p;
      blocks_.push_back({neighbours[j][p], j, offset, stride_[j]});
      if (neighbours[j][p] == j) diagonal_offset_[j] = offset;
    }
  }
  outer[3 * n] = nnz;
  auto offset_of = [&](int row, int col) {
    const auto& list = neighbours[col];
    const int p = static_cast<int>(std::lower_bound(list.begin(), list.end(), row) - list.begin());
    return column_start[col] + 3 * p;
  };
  for (const Spring& s : model.springs()) {
    spring_offset_ab_.push_back(offset_of(s.a, s.b));
    spring_offset_ba_.push_back(offset_of(s.b, s.a));
    spring_ends_.emplace_back(s.a, s.b);
  }
  SetZero();
}

void SystemMatrix::SetZero() {
  std::fill_n(matrix_.valuePtr(), matrix_.nonZeros(), 0.0);
}

void SystemMatrix::AddAt(int offset, int stride, const Eigen::Matrix3d& block, double sign) {
  double* v = matrix_.valuePtr() + offset;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) v[c * stride + r] += sign * block(r, c);
  }
}

void SystemMatrix::AddToDiagonal(int i, const Eigen::Matrix3d& block) {
  AddAt(diagonal_offset_[i], stride_[i], block, 1.0);
}

void SystemMatrix::AddSpringCoupling(int spring, const Eigen::Matrix3d& block) {
  const auto [a, b] = spring_ends_[spring];
  AddAt(diagonal_offset_[a], stride_[a], block, 1.0);
  AddAt(diagonal_offset_[b], stride_[b], block, 1.0);
  AddAt(spring_offset_ab_[spring], stride_[b], block, -1.0);
  AddAt(spring_offset_ba_[spring], stride_[a], block, -1.0);
}

void SystemMatrix::Multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  // A is symmetric: reading the column-major arrays as rows gives a gather product.
  y.noalias() = matrix_.transpose() * x;
}

Eigen::Matrix3d SystemMatrix::DiagonalBlock(int i) const {
  const double* v = matrix_.valuePtr() + diagonal_offset_[i];
  Eigen::Matrix3d block;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) block(r, c) = v[c * stride_[i] + r];
  }
  return block;
}

}  // namespace costume::sim
