#include "sim_core/hierarchy/quincunx_pyramid.h"

#include <utility>

#include "sim_core/hierarchy/mesh_coarsening.h"

namespace costume::sim {

namespace {

/// A level-0 particle's lattice coordinates (column, row).
Eigen::Vector2i Coordinates(const ClothModel& level0, int g) {
  return {g % level0.lattice_cols(), g / level0.lattice_cols()};
}

/// Whether lattice coordinates lie on the panel.
bool OnPanel(const ClothModel& level0, const Eigen::Vector2i& x) {
  return x.x() >= 0 && x.y() >= 0 && x.x() < level0.lattice_cols() && x.y() < level0.lattice_rows();
}

/// Quincunx selection: p + q even, (p, q) the coordinates in the level's basis (u, v).
bool IsKept(const Eigen::Vector2i& x, const Eigen::Vector2i& u, const Eigen::Vector2i& v) {
  const int norm2 = u.squaredNorm();
  const int p = x.dot(u) / norm2, q = x.dot(v) / norm2;
  return (p + q) % 2 == 0;
}

/// Spring constants of level l+1 from those of level l (docs/pyramid.md): the rotated
/// lattice's structural springs run where level l's shear springs ran and carry twice their
/// constant; its shear springs run along level l's axes over 2h and carry half the
/// structural constant; bending k = B / h² with h² doubled. Damping follows the springs.
KindConstants CoarseConstants(const KindConstants& fine) {
  constexpr int kS = static_cast<int>(SpringKind::kStructural);
  constexpr int kD = static_cast<int>(SpringKind::kShear);
  constexpr int kB = static_cast<int>(SpringKind::kBending);
  KindConstants coarse;
  coarse.stiffness[kS] = 2.0 * fine.stiffness[kD];
  coarse.stiffness[kD] = 0.5 * fine.stiffness[kS];
  coarse.stiffness[kB] = 0.5 * fine.stiffness[kB];
  coarse.damping[kS] = 2.0 * fine.damping[kD];
  coarse.damping[kD] = 0.5 * fine.damping[kS];
  coarse.damping[kB] = 0.5 * fine.damping[kB];
  return coarse;
}

KindConstants ConstantsOf(const ClothModel& model) {
  KindConstants constants;
  bool seen[3] = {false, false, false};
  for (const Spring& s : model.springs()) {
    const int kind = static_cast<int>(s.kind);
    if (seen[kind]) continue;
    seen[kind] = true;
    constants.stiffness[kind] = s.stiffness;
    constants.damping[kind] = s.damping;
  }
  return constants;
}

/// Level-0 indices of the particles a new level keeps, in level order.
std::vector<int> SelectKept(const ClothModel& level0, const PyramidLevel& fine) {
  std::vector<int> kept;
  for (int g : fine.level0_index) {
    if (IsKept(Coordinates(level0, g), fine.basis_u, fine.basis_v)) kept.push_back(g);
  }
  return kept;
}

}  // namespace

QuincunxPyramid::QuincunxPyramid(std::shared_ptr<const ClothModel> level0, int max_levels) {
  PyramidLevel base;
  base.model = std::move(level0);
  for (int i = 0; i < base.model->num_particles(); ++i) base.level0_index.push_back(i);
  levels_.push_back(std::move(base));
  constants_.push_back(ConstantsOf(*levels_[0].model));
  const bool lattice = levels_[0].model->lattice_rows() > 0;
  while (max_levels == 0 || num_levels() < max_levels) {
    const int before = num_levels();
    if (lattice) {
      AddLevel();
    } else {
      AddMeshLevel();
    }
    if (num_levels() == before) break;
  }
}

int QuincunxPyramid::MaxLevels(int rows, int cols) {
  ClothModelData data;
  data.lattice_rows = rows;
  data.lattice_cols = cols;
  data.rest_positions = Points::Zero(rows * cols, 3);
  data.masses = Eigen::VectorXd::Ones(rows * cols);
  data.areas = Eigen::VectorXd::Zero(rows * cols);
  PyramidLevel level;
  for (int i = 0; i < rows * cols; ++i) level.level0_index.push_back(i);
  const auto model = ClothModel::Create(data);
  int levels = 1;
  while (true) {
    const std::vector<int> kept = SelectKept(*model, level);
    if (static_cast<int>(kept.size()) < kMinParticles) return levels;
    level.level0_index = kept;
    const Eigen::Vector2i u = level.basis_u;
    level.basis_u = u + level.basis_v;
    level.basis_v = level.basis_v - u;
    ++levels;
  }
}

void QuincunxPyramid::AddLevel() {
  const PyramidLevel& fine = levels_.back();
  const ClothModel& level0 = *levels_[0].model;
  const ClothModel& fine_model = *fine.model;
  PyramidLevel coarse;
  coarse.level0_index = SelectKept(level0, fine);
  if (static_cast<int>(coarse.level0_index.size()) < kMinParticles) return;
  coarse.basis_u = fine.basis_u + fine.basis_v;
  coarse.basis_v = fine.basis_v - fine.basis_u;

  std::vector<int> index_of(level0.num_particles(), -1);
  for (std::size_t c = 0; c < coarse.level0_index.size(); ++c) {
    index_of[coarse.level0_index[c]] = static_cast<int>(c);
  }
  const int nc = static_cast<int>(coarse.level0_index.size());
  ClothModelData data;
  data.name = level0.name() + " level " + std::to_string(num_levels());
  data.rest_positions.resize(nc, 3);
  for (int c = 0; c < nc; ++c) data.rest_positions.row(c) = level0.rest_positions().row(coarse.level0_index[c]);
  data.masses = Eigen::VectorXd::Zero(nc);
  data.areas = Eigen::VectorXd::Zero(nc);
  data.drag = Eigen::VectorXd::Zero(nc);

  // Lumped Galerkin masses: each finer particle's mass goes to the coarse particles it is
  // interpolated from, in the interpolation's weights (so momentum and total mass are kept).
  coarse.kept.assign(fine_model.num_particles(), -1);
  coarse.interpolation_start.push_back(0);
  for (int f = 0; f < fine_model.num_particles(); ++f) {
    const int g = fine.level0_index[f];
    if (index_of[g] >= 0) {
      coarse.kept[f] = index_of[g];
      coarse.interpolation_from.push_back(index_of[g]);
    } else {
      const Eigen::Vector2i x = Coordinates(level0, g);
      for (const Eigen::Vector2i& d : {fine.basis_u, Eigen::Vector2i(-fine.basis_u),
                                       fine.basis_v, Eigen::Vector2i(-fine.basis_v)}) {
        const Eigen::Vector2i y = x + d;
        if (!OnPanel(level0, y)) continue;
        const int c = index_of[y.y() * level0.lattice_cols() + y.x()];
        if (c >= 0) coarse.interpolation_from.push_back(c);
      }
    }
    const int first = coarse.interpolation_start.back();
    const int count = static_cast<int>(coarse.interpolation_from.size()) - first;
    for (int k = first; k < first + count; ++k) {
      const int c = coarse.interpolation_from[k];
      data.masses[c] += fine_model.masses()[f] / count;
      data.areas[c] += fine_model.areas()[f] / count;
      data.drag[c] += fine_model.drag()[f] / count;
    }
    coarse.interpolation_start.push_back(first + count);
  }
  for (int p : fine_model.pinned()) {
    if (coarse.kept[p] >= 0) data.pinned.push_back(coarse.kept[p]);
  }

  // The level's own 12-neighbour lattice, with the dynamic-equivalent constants.
  const KindConstants constants = CoarseConstants(constants_.back());
  const Eigen::Vector2i u = coarse.basis_u, v = coarse.basis_v;
  const std::pair<Eigen::Vector2i, SpringKind> offsets[] = {
      {u, SpringKind::kStructural}, {v, SpringKind::kStructural},
      {u + v, SpringKind::kShear},  {u - v, SpringKind::kShear},
      {2 * u, SpringKind::kBending}, {2 * v, SpringKind::kBending}};
  for (int c = 0; c < nc; ++c) {
    const Eigen::Vector2i x = Coordinates(level0, coarse.level0_index[c]);
    for (const auto& [d, kind] : offsets) {
      const Eigen::Vector2i y = x + d;
      if (!OnPanel(level0, y)) continue;
      const int other = index_of[y.y() * level0.lattice_cols() + y.x()];
      if (other < 0) continue;
      const int k = static_cast<int>(kind);
      if (constants.stiffness[k] == 0.0 && constants.damping[k] == 0.0) continue;
      Spring s;
      s.a = c;
      s.b = other;
      s.kind = kind;
      s.stiffness = constants.stiffness[k];
      s.damping = constants.damping[k];
      s.rest_length = (data.rest_positions.row(other) - data.rest_positions.row(c)).norm();
      data.springs.push_back(s);
    }
  }
  coarse.model = ClothModel::Create(std::move(data));
  levels_.push_back(std::move(coarse));
  IndexRestriction();
  constants_.push_back(constants);
}

void QuincunxPyramid::AddMeshLevel() {
  const PyramidLevel& fine = levels_.back();
  std::optional<MeshCoarsening> step = CoarsenMesh(*fine.model, kMinParticles);
  if (!step) return;
  PyramidLevel coarse;
  for (int f : step->fine_index) coarse.level0_index.push_back(fine.level0_index[f]);
  coarse.kept = std::move(step->kept);
  coarse.interpolation_start = std::move(step->interpolation_start);
  coarse.interpolation_from = std::move(step->interpolation_from);
  step->coarse.name = levels_[0].model->name() + " level " + std::to_string(num_levels());
  coarse.model = ClothModel::Create(std::move(step->coarse));
  constants_.push_back(ConstantsOf(*coarse.model));
  levels_.push_back(std::move(coarse));
  IndexRestriction();
}

void QuincunxPyramid::Prolongate(int l, const Eigen::VectorXd& coarse, Eigen::VectorXd& fine,
                                 ThreadPool* pool) const {
  const PyramidLevel& level = levels_[l];
  ForEachParticleChunk(pool, static_cast<int>(level.kept.size()), [&](int begin, int end) {
    for (int f = begin; f < end; ++f) {
      const int first = level.interpolation_start[f], last = level.interpolation_start[f + 1];
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int k = first; k < last; ++k) sum += coarse.segment<3>(3 * level.interpolation_from[k]);
      fine.segment<3>(3 * f) = sum / std::max(1, last - first);
    }
  });
}

void QuincunxPyramid::Restrict(int l, const Eigen::VectorXd& fine, Eigen::VectorXd& coarse,
                               ThreadPool* pool) const {
  const PyramidLevel& level = levels_[l];
  const int nc = static_cast<int>(level.restriction_start.size()) - 1;
  ForEachParticleChunk(pool, nc, [&](int begin, int end) {
    for (int c = begin; c < end; ++c) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int k = level.restriction_start[c]; k < level.restriction_start[c + 1]; ++k) {
        const int f = level.restriction_from[k];
        const int count = level.interpolation_start[f + 1] - level.interpolation_start[f];
        sum += fine.segment<3>(3 * f) / count;
      }
      coarse.segment<3>(3 * c) = sum;
    }
  });
}

void QuincunxPyramid::IndexRestriction() {
  PyramidLevel& level = levels_.back();
  const int nc = level.model->num_particles();
  const int nf = static_cast<int>(level.kept.size());
  level.restriction_start.assign(nc + 1, 0);
  for (int k = 0; k < level.interpolation_start[nf]; ++k) {
    ++level.restriction_start[level.interpolation_from[k] + 1];
  }
  for (int c = 0; c < nc; ++c) level.restriction_start[c + 1] += level.restriction_start[c];
  level.restriction_from.resize(level.restriction_start[nc]);
  std::vector<int> next(level.restriction_start.begin(), level.restriction_start.end() - 1);
  for (int f = 0; f < nf; ++f) {  // ascending f: each coarse list ascends
    for (int k = level.interpolation_start[f]; k < level.interpolation_start[f + 1]; ++k) {
      level.restriction_from[next[level.interpolation_from[k]]++] = f;
    }
  }
}

void QuincunxPyramid::RestrictState(int l, const ClothState& level0, ClothState& out) const {
  const std::vector<int>& index = levels_[l].level0_index;
  for (std::size_t p = 0; p < index.size(); ++p) {
    out.positions.row(p) = level0.positions.row(index[p]);
    out.velocities.row(p) = level0.velocities.row(index[p]);
  }
  out.time = level0.time;
}

void QuincunxPyramid::RestrictConstraints(int l, const Constraints& level0, Constraints& out) const {
  out.Clear();
  // Walk the chain of kept maps: a level-0 constrained particle maps to level l if kept at
  // every level on the way.
  for (int g : level0.constrained()) {
    int index = g;
    for (int k = 1; k <= l && index >= 0; ++k) index = levels_[k].kept[index];
    if (index < 0) continue;
    const Eigen::Vector3d prescribed = level0.prescribed().segment<3>(3 * g);
    if (level0.num_constrained_directions(g) == 3) {
      out.Fix(index, prescribed);
    } else {
      out.ConstrainNormal(index, level0.normal(g), level0.normal(g).dot(prescribed));
    }
  }
}

void QuincunxPyramid::UpdateRegion(std::shared_ptr<const ClothModel> edited_level0,
                                   const Points& positions, const std::vector<int>& region) {
  levels_[0].model = std::move(edited_level0);
  std::vector<bool> in_region(levels_[0].model->num_particles(), false);
  for (int g : region) in_region[g] = true;
  for (int l = 1; l < num_levels(); ++l) {
    PyramidLevel& level = levels_[l];
    Eigen::VectorXd rest(level.model->num_springs());
    bool changed = false;
    for (int k = 0; k < level.model->num_springs(); ++k) {
      const Spring& s = level.model->springs()[k];
      const int ga = level.level0_index[s.a], gb = level.level0_index[s.b];
      rest[k] = s.rest_length;
      if (in_region[ga] && in_region[gb]) {
        rest[k] = (positions.row(gb) - positions.row(ga)).norm();
        changed = true;
      }
    }
    if (changed) level.model = level.model->WithRestLengths(rest);
  }
}

std::vector<std::shared_ptr<const ClothModel>> QuincunxPyramid::LevelModels() const {
  std::vector<std::shared_ptr<const ClothModel>> models;
  for (const PyramidLevel& level : levels_) models.push_back(level.model);
  return models;
}

void QuincunxPyramid::RestoreLevelModels(
    const std::vector<std::shared_ptr<const ClothModel>>& models) {
  for (std::size_t l = 0; l < levels_.size() && l < models.size(); ++l) levels_[l].model = models[l];
}

}  // namespace costume::sim
