#pragma once
/// @file
/// The implicit step's system matrix A = M − h ∂f/∂v − h² ∂f/∂x (3n×3n, symmetric), stored
/// with a pattern fixed by the model's springs so that each step only rewrites values.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <utility>
#include <vector>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// A symmetric block-sparse matrix with one 3×3 block per particle (diagonal) and per
/// spring (both off-diagonal blocks). Column-major; because A is symmetric, the same arrays
/// read row-major give A too, which the product uses.
class SystemMatrix {
 public:
  /// Builds the pattern of `model`'s springs. Allocates; call once per model revision.
  explicit SystemMatrix(const ClothModel& model);

  /// Zeroes all values. Never allocates.
  void SetZero();
  /// Adds `block` to diagonal block (i, i). Never allocates.
  void AddToDiagonal(int i, const Eigen::Matrix3d& block);
  /// Adds a spring's coupling: +block on (a, a) and (b, b), −block on (a, b) and (b, a).
  /// `spring` indexes model.springs(). Never allocates.
  void AddSpringCoupling(int spring, const Eigen::Matrix3d& block);
  /// y = A x (3n vectors). Never allocates.
  void Multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  /// Diagonal block (i, i).
  Eigen::Matrix3d DiagonalBlock(int i) const;

  /// Calls visit(i, j, offset, stride) for every stored block: entry (3i + r, 3j + c) lives at
  /// values()[offset + c·stride + r].
  template <typename Visit>
  void ForEachBlock(Visit&& visit) const {
    for (const Block& b : blocks_) visit(b.row, b.col, b.offset, b.stride);
  }

  int num_particles() const { return num_particles_; }
  const Eigen::SparseMatrix<double>& matrix() const { return matrix_; }
  double* values() { return matrix_.valuePtr(); }

 private:
  struct Block {
    int row, col, offset, stride;
  };
  /// Adds a block at (value offset, column stride); `sign` ±1.
  void AddAt(int offset, int stride, const Eigen::Matrix3d& block, double sign);

  int num_particles_;
  Eigen::SparseMatrix<double> matrix_;  // column-major, sorted rows
  std::vector<Block> blocks_;
  std::vector<int> diagonal_offset_;    // per particle
  std::vector<int> stride_;             // per particle: 3 × its number of blocks in a column
  std::vector<int> spring_offset_ab_;   // block (a, b) per spring
  std::vector<int> spring_offset_ba_;   // block (b, a) per spring
  std::vector<std::pair<int, int>> spring_ends_;
};

}  // namespace costume::sim
