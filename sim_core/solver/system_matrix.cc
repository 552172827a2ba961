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
  row_start_.assign(n + 1, 0);
  for (int i = 0; i < n; ++i) {
    std::sort(neighbours[i].begin(), neighbours[i].end());
    row_start_[i + 1] = row_start_[i] + static_cast<int>(neighbours[i].size());
    block_col_.insert(block_col_.end(), neighbours[i].begin(), neighbours[i].end());
  }
  values_.assign(9 * block_col_.size(), 0.0);
  auto block_of = [&](int row, int col) {
    const auto first = block_col_.begin() + row_start_[row];
    const auto last = block_col_.begin() + row_start_[row + 1];
    return static_cast<int>(std::lower_bound(first, last, col) - block_col_.begin());
  };
  diagonal_block_.resize(n);
  for (int i = 0; i < n; ++i) diagonal_block_[i] = block_of(i, i);
  for (const Spring& s : model.springs()) {
    spring_ends_.emplace_back(s.a, s.b);
    spring_blocks_.emplace_back(block_of(s.a, s.b), block_of(s.b, s.a));
  }
}

void SystemMatrix::SetZero() { std::fill(values_.begin(), values_.end(), 0.0); }

void SystemMatrix::AddToDiagonal(int i, const Eigen::Matrix3d& block) {
  mutable_block(diagonal_block_[i]) += block;
}

void SystemMatrix::AddSpringCoupling(int spring, const Eigen::Matrix3d& block) {
  const auto [a, b] = spring_ends_[spring];
  const auto [ab, ba] = spring_blocks_[spring];
  mutable_block(diagonal_block_[a]) += block;
  mutable_block(diagonal_block_[b]) += block;
  mutable_block(ab) -= block;
  mutable_block(ba) -= block;
}

void SystemMatrix::Multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  const double* v = values_.data();
  const double* xs = x.data();
  for (int i = 0; i < num_particles_; ++i) {
    double y0 = 0.0, y1 = 0.0, y2 = 0.0;
    for (int b = row_start_[i]; b < row_start_[i + 1]; ++b) {
      const double* m = v + 9 * b;
      const double* xj = xs + 3 * block_col_[b];
      y0 += m[0] * xj[0] + m[1] * xj[1] + m[2] * xj[2];
      y1 += m[3] * xj[0] + m[4] * xj[1] + m[5] * xj[2];
      y2 += m[6] * xj[0] + m[7] * xj[1] + m[8] * xj[2];
    }
    y[3 * i] = y0;
    y[3 * i + 1] = y1;
    y[3 * i + 2] = y2;
  }
}

Eigen::Matrix3d SystemMatrix::DiagonalBlock(int i) const { return block(diagonal_block_[i]); }

}  // namespace costume::sim
