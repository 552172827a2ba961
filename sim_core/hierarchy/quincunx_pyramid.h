#pragma once
/// @file
/// The quincunx pyramid of a lattice cloth (paper §3.2, Figure 3; docs/pyramid.md).
/// Level l+1 keeps the particles of level l whose coordinates (p, q) in level l's own lattice
/// basis have p + q even: a lattice rotated 45° with spacing ×√2. Twice applied, spacing 2h
/// on the original axes. Every level is a full 12-neighbour mass-spring model, its masses and
/// spring constants the dynamic equivalent of the level below (docs/pyramid.md derives them).
/// Because coarse particles are a subset of the fine ones, restricting a state or a
/// constraint is a gather; prolongation gives each dropped particle the mean of its kept
/// structural neighbours. Models that are not one lattice panel (sewn garments, meshes from
/// files) are coarsened by the independent-set rule of mesh_coarsening.h instead, which
/// reduces to quincunx sampling on a lattice.

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"
#include "sim_core/common/thread_pool.h"
#include "sim_core/solver/constraints.h"

namespace costume::sim {

/// One level of the pyramid.
struct PyramidLevel {
  std::shared_ptr<const ClothModel> model;
  /// Level-0 particle of each particle of this level.
  std::vector<int> level0_index;
  /// Lattice basis of this level in level-0 lattice steps (column, row): its structural
  /// springs run along ±basis_u and ±basis_v.
  Eigen::Vector2i basis_u{1, 0};
  Eigen::Vector2i basis_v{0, 1};
  /// For levels >= 1, how the next finer level (l − 1) is interpolated from this one: finer
  /// particle f takes the mean of this level's particles interpolation_from[start[f] ..
  /// start[f + 1]) (itself alone when it was kept).
  std::vector<int> interpolation_start;
  std::vector<int> interpolation_from;
  /// For levels >= 1, this level's index of each finer particle, −1 when dropped.
  std::vector<int> kept;
  /// For levels >= 1, the transpose of the interpolation: the finer particles that particle c
  /// of this level is interpolated into, restriction_from[restriction_start[c] ..
  /// restriction_start[c + 1]), in ascending order (so that Pᵀ gathers in the order the
  /// scatter over finer particles would add).
  std::vector<int> restriction_start;
  std::vector<int> restriction_from;
};

/// Spring constants and damping of each kind on one level (uniform on a lattice panel; on
/// a general mesh's levels each spring has its own, and this holds the first of each kind).
struct KindConstants {
  double stiffness[3] = {0, 0, 0};  // indexed by SpringKind
  double damping[3] = {0, 0, 0};
};

class QuincunxPyramid {
 public:
  /// Builds up to `max_levels` levels counting level 0 (0 = as many as the lattice allows:
  /// coarsening stops before a level would have fewer than kMinParticles particles).
  /// A model that is not a single lattice panel (lattice_rows() == 0) is coarsened by
  /// CoarsenMesh until a level would have fewer than kMinParticles particles or coarsening
  /// stalls.
  QuincunxPyramid(std::shared_ptr<const ClothModel> level0, int max_levels);

  /// The smallest level the pyramid builds.
  static constexpr int kMinParticles = 25;

  /// Levels a rows × cols lattice allows (what max_levels = 0 builds).
  static int MaxLevels(int rows, int cols);

  int num_levels() const { return static_cast<int>(levels_.size()); }
  const PyramidLevel& level(int l) const { return levels_[l]; }
  const KindConstants& constants(int l) const { return constants_[l]; }

  /// fine (3·n_{l−1}) = P_l coarse (3·n_l): the coarse value at kept particles, the mean of
  /// the kept neighbours at dropped ones. Never allocates.
  /// `pool` (may be null) spreads the finer particles over its threads. Never allocates.
  void Prolongate(int l, const Eigen::VectorXd& coarse, Eigen::VectorXd& fine,
                  ThreadPool* pool = nullptr) const;
  /// coarse = P_lᵀ fine, each coarse particle gathered on one of `pool`'s threads (may be
  /// null): the same bits either way. Never allocates.
  void Restrict(int l, const Eigen::VectorXd& fine, Eigen::VectorXd& coarse,
                ThreadPool* pool = nullptr) const;
  /// Gathers level 0's positions and velocities into level l's (preallocated) state.
  void RestrictState(int l, const ClothState& level0, ClothState& out) const;
  /// Copies level 0's constraints onto level l's kept particles (pins and contacts alike).
  void RestrictConstraints(int l, const Constraints& level0, Constraints& out) const;

  /// After an edit set the rest lengths of level 0's springs in `region` (level-0 particle
  /// indices) to their lengths at `positions` [m] (paper §5.3), brings every coarse level in
  /// line: springs of each level with both ends in the region get their current lengths as
  /// rest lengths; nothing else is rebuilt. `edited_level0` is the edited level-0 model.
  void UpdateRegion(std::shared_ptr<const ClothModel> edited_level0, const Points& positions,
                    const std::vector<int>& region);

  /// Every level's model, level 0 first: what undoing an edit puts back.
  std::vector<std::shared_ptr<const ClothModel>> LevelModels() const;
  /// Puts back models LevelModels returned earlier for this pyramid (same topology).
  void RestoreLevelModels(const std::vector<std::shared_ptr<const ClothModel>>& models);

 private:
  void AddLevel();
  void AddMeshLevel();
  /// Fills the restriction index of the last level from its interpolation.
  void IndexRestriction();
  std::vector<PyramidLevel> levels_;
  std::vector<KindConstants> constants_;
};

}  // namespace costume::sim
