#pragma once
/// @file
/// The implicit step's system matrix A = M − h ∂f/∂v − h² ∂f/∂x (3n×3n, symmetric), stored
/// the way it is built: one 3×3 block per particle (the diagonal) and one symmetric 3×3
/// coupling block B_s per spring s = (a, b), which puts +B_s on (a, a) and (b, b) and −B_s on
/// (a, b) and (b, a). Compared with block-compressed rows (13 blocks of 9 doubles per particle
/// of a 12-neighbour lattice) this stores less than half the bytes. The product (most of a PCG
/// iteration and of a multigrid smoothing sweep) goes row by row through an index of each
/// particle's springs and gathers: it reads each coupling block twice, but writes every y_i
/// once from registers. Streaming the springs and scattering into y_a and y_b instead was
/// 1.3–1.4× slower at N = 65 and 129 (measured): consecutive springs share a particle, and
/// each update of y_a waits for the previous one's store.

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/common/thread_pool.h"

namespace costume::sim {

/// A symmetric block-sparse matrix with one 3×3 block per particle (diagonal) and one
/// symmetric 3×3 coupling block per spring.
class SystemMatrix {
 public:
  /// Takes the spring ends of `model`. Allocates; call once per model revision.
  explicit SystemMatrix(const ClothModel& model);
  /// A matrix over `num_particles` particles coupling the given pairs (a, b), a != b, each
  /// pair at most once: any symmetric block-sparse matrix fits, a pair's coupling block
  /// being minus its off-diagonal block (the multigrid's Galerkin coarse operators).
  /// Allocates.
  SystemMatrix(int num_particles, std::vector<std::pair<int, int>> pairs);

  /// Zeroes all values. Never allocates.
  void SetZero();
  /// Adds `block` to diagonal block (i, i). Never allocates.
  void AddToDiagonal(int i, const Eigen::Matrix3d& block);
  /// Adds a spring's coupling: +block on (a, a) and (b, b), −block on (a, b) and (b, a);
  /// `block` must be symmetric (its upper triangle is used). `spring` indexes
  /// model.springs(). Never allocates.
  void AddSpringCoupling(int spring, const Eigen::Matrix3d& block);
  /// The same for the block identity·I + along·u uᵀ (a spring's closed form), without
  /// forming it. Never allocates.
  void AddSpringCoupling(int spring, double identity, double along, const Eigen::Vector3d& u);
  /// Sets spring s's coupling block to identity·I + along·u uᵀ without touching the diagonal
  /// (AddCouplingsToDiagonals adds it there afterwards): springs can be set in parallel.
  /// Never allocates.
  void SetSpringCoupling(int spring, double identity, double along, const Eigen::Vector3d& u);
  /// Adds every coupling block to the diagonal blocks of its two particles, rows [begin, end),
  /// each row in spring order: the sums AddSpringCoupling would have made spring by spring,
  /// to the bit. Never allocates.
  void AddCouplingsToDiagonals(int begin, int end);
  /// out_i += Σ ±v_s over the springs s of particle i in spring order, + where i is the
  /// spring's first particle, − where it is its second (v: 3 per spring, out: 3n), rows
  /// [begin, end). Never allocates.
  void AddSpringVectors(int begin, int end, const Eigen::VectorXd& v, Eigen::VectorXd& out) const;
  /// y = A x (3n vectors; y must not alias x), its rows spread over `pool`'s threads when
  /// one is given (each row is computed alike either way: the same bits). Never allocates.
  void Multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, ThreadPool* pool = nullptr) const;
  /// Diagonal block (i, i), springs included.
  Eigen::Matrix3d DiagonalBlock(int i) const;
  /// Coupling block B_s of spring s: A gets −B_s on (a, b) and (b, a).
  Eigen::Matrix3d SpringBlock(int spring) const;

  int num_particles() const { return num_particles_; }
  int num_springs() const { return static_cast<int>(spring_ends_.size()); }
  /// Particles (a, b) of spring s.
  const std::pair<int, int>& spring_ends(int spring) const { return spring_ends_[spring]; }

  /// The stored values, for products that write them in place: 9 per diagonal block
  /// (row-major, full, springs included) and 6 per coupling block (xx, xy, xz, yy, yz, zz).
  double* diagonal_values() { return diagonal_.data(); }
  const double* diagonal_values() const { return diagonal_.data(); }
  double* coupling_values() { return coupling_.data(); }
  const double* coupling_values() const { return coupling_.data(); }

 private:
  int num_particles_;
  std::vector<double> diagonal_;                   // 9 per particle, row-major
  std::vector<double> coupling_;                   // 6 per spring: xx, xy, xz, yy, yz, zz
  std::vector<std::pair<int, int>> spring_ends_;   // (a, b) per spring
  // Row index for the product: row i's entries are [row_start_[i], row_start_[i + 1]) of
  // row_entries_, each (the other particle, the spring).
  std::vector<int> row_start_;
  std::vector<std::pair<int, int>> row_entries_;
  void BuildRowIndex();
  /// Rows [begin, end) of y = A x.
  void MultiplyRows(int begin, int end, const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
};

}  // namespace costume::sim
