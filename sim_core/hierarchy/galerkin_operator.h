#pragma once
/// @file
/// The Galerkin coarse operator A_{l+1} = P_lᵀ A_l P_l of one pyramid level, in SystemMatrix
/// form (docs/pyramid.md, "Galerkin coarse operators"). P_l has one scalar weight per (fine,
/// coarse) particle pair, so every 3×3 block of the product is a weighted sum of A_l's
/// blocks: the symbolic part (the coarse pairs and, for each coarse block, which fine blocks
/// it sums with which weights) is built once per pattern; the numeric part each step is one
/// pass over that list and never allocates.

#include <utility>
#include <vector>

#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

/// One summand of the product: coarse block `target` += weight · fine block `source`
/// (upper triangles; blocks indexed by particle for diagonals, by pair for couplings).
struct GalerkinTerm {
  int target;
  int source;
  double weight;
};

class GalerkinOperator {
 public:
  /// The product for fine matrices with the pattern of `fine` (values ignored) and the
  /// prolongation P of `coarse_level` (a pyramid level >= 1, whose interpolation reads
  /// `num_coarse` particles). Allocates; build once per pyramid.
  GalerkinOperator(const SystemMatrix& fine, const PyramidLevel& coarse_level, int num_coarse);

  /// A zero coarse matrix with the product's pattern (num_coarse particles, one coupling per
  /// coarse pair the product touches). Allocates.
  SystemMatrix MakeCoarseMatrix() const;

  /// coarse = Pᵀ fine P. `fine` must have the construction's pattern and symmetric blocks,
  /// `coarse` come from MakeCoarseMatrix. Each coarse block is summed on one of `pool`'s
  /// threads (may be null), its terms in the same order either way: the same bits. Never
  /// allocates.
  void Compute(const SystemMatrix& fine, SystemMatrix& coarse, ThreadPool* pool = nullptr) const;

  /// Coarse coupling pairs (a < b).
  const std::vector<std::pair<int, int>>& pairs() const { return pairs_; }

 private:
  int num_fine_;
  int num_fine_springs_;
  int num_coarse_;
  std::vector<std::pair<int, int>> pairs_;
  // By kind of (target, source): diagonal ← diagonal, diagonal ← coupling, coupling ←
  // diagonal, coupling ← coupling. Coupling targets store −(the coarse off-diagonal block).
  std::vector<GalerkinTerm> diagonal_from_diagonal_, diagonal_from_coupling_;
  std::vector<GalerkinTerm> coupling_from_diagonal_, coupling_from_coupling_;
  // For each list above, where the terms of each chunk of ThreadPool::kChunkParticles
  // targets start (the lists are sorted by target).
  std::vector<int> diagonal_from_diagonal_chunks_, diagonal_from_coupling_chunks_;
  std::vector<int> coupling_from_diagonal_chunks_, coupling_from_coupling_chunks_;
};

}  // namespace costume::sim
