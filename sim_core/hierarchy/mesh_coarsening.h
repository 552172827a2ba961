#pragma once
/// @file
/// One coarsening step for a cloth model of any topology (several sewn panels, a mesh read
/// from a file): the general-mesh analogue of quincunx sampling (DESIGN.md, paper §3.2;
/// derivation in docs/pyramid.md, "General meshes").
///
/// Kept particles are a maximal independent set of the structural-spring graph, chosen
/// greedily with pinned particles first and then in the order of a two-colouring (even
/// breadth-first depth) — on a lattice panel that is exactly the quincunx set (i + j even),
/// on any quad mesh that can be two-coloured the same checkerboard however it is numbered.
/// A dropped particle is interpolated as the mean of its kept structural neighbours (with
/// those of its dropped neighbours when it has only one). Coarse springs join the kept
/// particles a dropped particle is interpolated from, and the ends of a structural spring
/// between two dropped particles; a pair is structural where a path between its ends turns,
/// or where it is no coarse cell's diagonal. Their stiffnesses are fitted so that every
/// coarse particle's share of the stretch/shear stiffness tensor Σ ½kℓ² n⊗n⊗n⊗n equals the
/// fine particles' it stands for, which on a lattice gives the quincunx rule K_s = 2k_d,
/// K_d = k_s/2 exactly. Bending springs keep the fine bending rigidity B = kℓ²/4 at their
/// new length.

#include <optional>
#include <vector>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// A coarse level made from a finer one.
struct MeshCoarsening {
  ClothModelData coarse;
  /// For each fine particle, its coarse index, −1 when dropped.
  std::vector<int> kept;
  /// Fine index of each coarse particle.
  std::vector<int> fine_index;
  /// Fine particle f is interpolated as the mean of the coarse particles
  /// interpolation_from[interpolation_start[f] .. interpolation_start[f + 1]).
  std::vector<int> interpolation_start;
  std::vector<int> interpolation_from;
};

/// Coarsens `fine` once. Returns nullopt when the coarse level would have fewer than
/// `min_particles` particles or keep more than 3/4 of the fine ones (coarsening has stalled,
/// e.g. on a graph with no structural springs). Springs of the coarse model carry level-0
/// rest lengths from `fine`'s rest positions.
std::optional<MeshCoarsening> CoarsenMesh(const ClothModel& fine, int min_particles);

}  // namespace costume::sim
