#include "sim_core/hierarchy/galerkin_operator.h"

#include <algorithm>
#include <cstdint>

namespace costume::sim {

namespace {

/// The upper triangle of a row-major 3×3 block, in a coupling block's order.
constexpr int kDiagonalUpper[6] = {0, 1, 2, 4, 5, 8};
/// A coupling block's six values in the same order.
constexpr int kCouplingUpper[6] = {0, 1, 2, 3, 4, 5};

std::int64_t PairKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::int64_t>(a) << 32) | static_cast<std::uint32_t>(b);
}

/// Sorts terms by (target, source) and merges those with the same pair: one pass per
/// step over a list in target order.
void Merge(std::vector<GalerkinTerm>& terms) {
  std::sort(terms.begin(), terms.end(), [](const GalerkinTerm& x, const GalerkinTerm& y) {
    return x.target != y.target ? x.target < y.target : x.source < y.source;
  });
  std::size_t out = 0;
  for (std::size_t i = 0; i < terms.size(); ++i) {
    if (out > 0 && terms[out - 1].target == terms[i].target &&
        terms[out - 1].source == terms[i].source) {
      terms[out - 1].weight += terms[i].weight;
    } else {
      terms[out++] = terms[i];
    }
  }
  terms.resize(out);
  terms.shrink_to_fit();
}

/// target block += weight · source block over the upper triangles (strides 9 for diagonal
/// blocks, 6 for coupling blocks).
template <int kSourceStride, int kTargetStride>
void AddTerms(const GalerkinTerm* first, const GalerkinTerm* last, const double* source,
              double* target) {
  constexpr const int* from = kSourceStride == 9 ? kDiagonalUpper : kCouplingUpper;
  constexpr const int* to = kTargetStride == 9 ? kDiagonalUpper : kCouplingUpper;
  for (const GalerkinTerm* t = first; t != last; ++t) {
    const double* s = source + kSourceStride * static_cast<std::size_t>(t->source);
    double* d = target + kTargetStride * static_cast<std::size_t>(t->target);
    for (int e = 0; e < 6; ++e) d[to[e]] += t->weight * s[from[e]];
  }
}

/// Where the terms of each chunk of targets start in `terms` (sorted by target), and the end.
std::vector<int> ChunkStarts(const std::vector<GalerkinTerm>& terms, int num_targets) {
  std::vector<int> starts;
  for (int c = 0; c <= ThreadPool::NumChunks(num_targets); ++c) {
    const int target = c * ThreadPool::kChunkParticles;
    starts.push_back(static_cast<int>(
        std::lower_bound(terms.begin(), terms.end(), target,
                         [](const GalerkinTerm& t, int value) { return t.target < value; }) -
        terms.begin()));
  }
  return starts;
}

/// The terms of `terms` chunk by chunk of targets, on `pool` (may be null).
template <int kSourceStride, int kTargetStride>
void AddTermsByChunk(ThreadPool* pool, const std::vector<GalerkinTerm>& terms,
                     const std::vector<int>& chunk_starts, int num_targets, const double* source,
                     double* target) {
  ForEachParticleChunk(pool, num_targets, [&](int begin, int) {
    const int c = begin / ThreadPool::kChunkParticles;
    AddTerms<kSourceStride, kTargetStride>(terms.data() + chunk_starts[c],
                                           terms.data() + chunk_starts[c + 1], source, target);
  });
}

}  // namespace

GalerkinOperator::GalerkinOperator(const SystemMatrix& fine, const PyramidLevel& coarse_level,
                                   int num_coarse)
    : num_fine_(fine.num_particles()),
      num_fine_springs_(fine.num_springs()),
      num_coarse_(num_coarse) {
  const std::vector<int>& start = coarse_level.interpolation_start;
  const std::vector<int>& from = coarse_level.interpolation_from;
  auto weight = [&](int f) { return 1.0 / std::max(1, start[f + 1] - start[f]); };
  // Pairs are first collected as keys (target = key index), then numbered in sorted order
  // so the coarse product streams them by first particle.
  std::vector<std::int64_t> keys;
  std::vector<GalerkinTerm> coupling_from_diagonal, coupling_from_coupling;
  for (int f = 0; f < num_fine_; ++f) {
    const double w = weight(f);
    for (int k1 = start[f]; k1 < start[f + 1]; ++k1) {
      diagonal_from_diagonal_.push_back({from[k1], f, w * w});
      for (int k2 = k1 + 1; k2 < start[f + 1]; ++k2) {
        keys.push_back(PairKey(from[k1], from[k2]));
        coupling_from_diagonal.push_back({static_cast<int>(keys.size()) - 1, f, -w * w});
      }
    }
  }
  // A spring's −B on (a, b) and (b, a): coarse (I, J) with I from a and J from b gets
  // w_aI w_bJ (−B) (its transpose on (J, I)); on the diagonal both orientations land.
  for (int s = 0; s < num_fine_springs_; ++s) {
    const auto [a, b] = fine.spring_ends(s);
    const double w = weight(a) * weight(b);
    for (int ka = start[a]; ka < start[a + 1]; ++ka) {
      for (int kb = start[b]; kb < start[b + 1]; ++kb) {
        if (from[ka] == from[kb]) {
          diagonal_from_coupling_.push_back({from[ka], s, -2.0 * w});
        } else {
          keys.push_back(PairKey(from[ka], from[kb]));
          coupling_from_coupling.push_back({static_cast<int>(keys.size()) - 1, s, w});
        }
      }
    }
  }
  std::vector<std::int64_t> sorted = keys;
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  pairs_.reserve(sorted.size());
  for (std::int64_t key : sorted) {
    pairs_.emplace_back(static_cast<int>(key >> 32), static_cast<int>(key & 0xffffffff));
  }
  auto renumber = [&](std::vector<GalerkinTerm>& terms) {
    for (GalerkinTerm& t : terms) {
      t.target = static_cast<int>(std::lower_bound(sorted.begin(), sorted.end(), keys[t.target]) -
                                  sorted.begin());
    }
  };
  renumber(coupling_from_diagonal);
  renumber(coupling_from_coupling);
  coupling_from_diagonal_ = std::move(coupling_from_diagonal);
  coupling_from_coupling_ = std::move(coupling_from_coupling);
  Merge(diagonal_from_diagonal_);
  Merge(diagonal_from_coupling_);
  Merge(coupling_from_diagonal_);
  Merge(coupling_from_coupling_);
  const int num_pairs = static_cast<int>(pairs_.size());
  diagonal_from_diagonal_chunks_ = ChunkStarts(diagonal_from_diagonal_, num_coarse_);
  diagonal_from_coupling_chunks_ = ChunkStarts(diagonal_from_coupling_, num_coarse_);
  coupling_from_diagonal_chunks_ = ChunkStarts(coupling_from_diagonal_, num_pairs);
  coupling_from_coupling_chunks_ = ChunkStarts(coupling_from_coupling_, num_pairs);
}

SystemMatrix GalerkinOperator::MakeCoarseMatrix() const { return SystemMatrix(num_coarse_, pairs_); }

void GalerkinOperator::Compute(const SystemMatrix& fine, SystemMatrix& coarse,
                               ThreadPool* pool) const {
  coarse.SetZero();
  const double* fine_diagonal = fine.diagonal_values();
  const double* fine_coupling = fine.coupling_values();
  double* coarse_diagonal = coarse.diagonal_values();
  double* coarse_coupling = coarse.coupling_values();
  const int num_pairs = static_cast<int>(pairs_.size());
  // List by list, as serially: a diagonal block gets its diagonal terms before its coupling
  // terms.
  AddTermsByChunk<9, 9>(pool, diagonal_from_diagonal_, diagonal_from_diagonal_chunks_,
                        num_coarse_, fine_diagonal, coarse_diagonal);
  AddTermsByChunk<6, 9>(pool, diagonal_from_coupling_, diagonal_from_coupling_chunks_,
                        num_coarse_, fine_coupling, coarse_diagonal);
  AddTermsByChunk<9, 6>(pool, coupling_from_diagonal_, coupling_from_diagonal_chunks_, num_pairs,
                        fine_diagonal, coarse_coupling);
  AddTermsByChunk<6, 6>(pool, coupling_from_coupling_, coupling_from_coupling_chunks_, num_pairs,
                        fine_coupling, coarse_coupling);
  for (int i = 0; i < num_coarse_; ++i) {
    double* d = coarse_diagonal + 9 * static_cast<std::size_t>(i);
    d[3] = d[1];
    d[6] = d[2];
    d[7] = d[5];
  }
}

}  // namespace costume::sim
