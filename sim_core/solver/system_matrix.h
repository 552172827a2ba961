#pragma once
/// @file
/// The implicit step's system matrix A = M − h ∂f/∂v − h² ∂f/∂x (3n×3n, symmetric), stored
/// as 3×3 blocks in block-compressed rows with a pattern fixed by the model's springs, so
/// each step only rewrites values and the product streams contiguous blocks.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <utility>
#include <vector>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// A symmetric block-sparse matrix with one 3×3 block per particle (diagonal) and one per
/// spring end (off-diagonal). Blocks are stored row-major, 9 doubles each.
class SystemMatrix {
 public:
  /// Builds the pattern of `model`'s springs. Allocates; call once per model revision.
  explicit SystemMatrix(const ClothModel& model);

  /// Zeroes all values. Never allocates.
  void SetZero();
  /// Adds `block` to diagonal block (i, i). Never allocates.
  void AddToDiagonal(int i, const Eigen::Matrix3d& block);
  /// Adds a spring's coupling: +block on (a, a) and (b, b), −block on (a, b) and (b, a);
  /// `block` must be symmetric. `spring` indexes model.springs(). Never allocates.
  void AddSpringCoupling(int spring, const Eigen::Matrix3d& block);
  /// y = A x (3n vectors). Never allocates.
  void Multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  /// Diagonal block (i, i).
  Eigen::Matrix3d DiagonalBlock(int i) const;

  int num_particles() const { return num_particles_; }
  int num_blocks() const { return static_cast<int>(block_col_.size()); }
  /// Block rows: blocks of row i are [row_start()[i], row_start()[i + 1]).
  const std::vector<int>& row_start() const { return row_start_; }
  /// Block column of each block.
  const std::vector<int>& block_col() const { return block_col_; }
  /// Block b as a row-major 3×3 matrix.
  Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> block(int b) const {
    return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(&values_[9 * b]);
  }

 private:
  using BlockRef = Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>;
  BlockRef mutable_block(int b) { return BlockRef(&values_[9 * b]); }

  int num_particles_;
  std::vector<int> row_start_;
  std::vector<int> block_col_;
  std::vector<double> values_;
  std::vector<int> diagonal_block_;                    // per particle
  std::vector<std::pair<int, int>> spring_ends_;       // (a, b) per spring
  std::vector<std::pair<int, int>> spring_blocks_;     // blocks (a, b), (b, a) per spring
};

}  // namespace costume::sim
