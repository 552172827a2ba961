#include "sim_core/hierarchy/mesh_coarsening.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <iterator>
#include <map>

namespace costume::sim {
namespace {

/// The 15 distinct components of the symmetric tensor n⊗n⊗n⊗n, each weighted by the square
/// root of its multiplicity so that the Euclidean norm of this vector is the tensor's
/// Frobenius norm.
using Tensor4 = Eigen::Matrix<double, 15, 1>;
Tensor4 Quartic(const Eigen::Vector3d& n) {
  static const double kFactorial[] = {1, 1, 2, 6, 24};
  Tensor4 t;
  int k = 0;
  for (int a = 4; a >= 0; --a) {
    for (int b = 4 - a; b >= 0; --b) {
      const int c = 4 - a - b;
      const double multiplicity = kFactorial[4] / (kFactorial[a] * kFactorial[b] * kFactorial[c]);
      t[k++] = std::sqrt(multiplicity) * std::pow(n.x(), a) * std::pow(n.y(), b) * std::pow(n.z(), c);
    }
  }
  return t;
}

/// Structural neighbours of every particle.
std::vector<std::vector<int>> StructuralNeighbours(const ClothModel& model) {
  std::vector<std::vector<int>> neighbours(model.num_particles());
  for (const Spring& s : model.springs()) {
    if (s.kind != SpringKind::kStructural) continue;
    neighbours[s.a].push_back(s.b);
    neighbours[s.b].push_back(s.a);
  }
  return neighbours;
}

/// Order of a breadth-first search over the structural graph, each component from its first
/// pinned particle (else its lowest index), with every particle's depth.
std::vector<int> BreadthFirstOrder(const ClothModel& model,
                                   const std::vector<std::vector<int>>& nbrs,
                                   std::vector<int>& depth) {
  depth.assign(model.num_particles(), -1);
  std::vector<int> order;
  order.reserve(model.num_particles());
  auto search_from = [&](int seed) {
    if (depth[seed] >= 0) return;
    depth[seed] = 0;
    order.push_back(seed);
    for (std::size_t head = order.size() - 1; head < order.size(); ++head) {
      for (int q : nbrs[order[head]]) {
        if (depth[q] < 0) depth[q] = depth[order[head]] + 1, order.push_back(q);
      }
    }
  };
  for (int p : model.pinned()) search_from(p);
  for (int p = 0; p < model.num_particles(); ++p) search_from(p);
  return order;
}

/// Greedy maximal independent set, taken in the order of a two-colouring: the pinned
/// particles an even number of structural steps from their component's seed, then the other
/// pinned ones (so pins survive), then every even particle in breadth-first order, then any
/// left free. On a quad mesh that can be two-coloured the even particles are one colour,
/// however it is numbered: the quincunx set on a lattice panel, the same checkerboard on a
/// garment read from a file. Index order, as before, took a scattered set on the MakeHuman suits,
/// whose dropped particles often had a single kept neighbour (docs/pyramid.md).
std::vector<bool> SelectKept(const ClothModel& model, const std::vector<std::vector<int>>& nbrs) {
  std::vector<bool> kept(model.num_particles(), false), blocked(model.num_particles(), false);
  auto take = [&](int p) {
    if (blocked[p]) return;
    kept[p] = blocked[p] = true;
    for (int q : nbrs[p]) blocked[q] = true;
  };
  std::vector<int> depth;
  const std::vector<int> order = BreadthFirstOrder(model, nbrs, depth);
  for (int p : model.pinned()) {
    if (depth[p] % 2 == 0) take(p);
  }
  for (int p : model.pinned()) take(p);
  for (int p : order) {
    if (depth[p] % 2 == 0) take(p);
  }
  for (int p = 0; p < model.num_particles(); ++p) take(p);
  return kept;
}

/// The kept particles each fine particle is interpolated from: itself when kept, else its
/// kept structural neighbours, and when it has only one, also those of its dropped
/// neighbours. Where a quad mesh cannot be two-coloured (a welded hem, a tube with an odd
/// number of quads around) a line of dropped particles has one kept neighbour each; copying
/// that one coarse particle left the coarse level without the stiffness across the line.
std::vector<std::vector<int>> Sources(const std::vector<std::vector<int>>& nbrs,
                                      const std::vector<int>& kept) {
  std::vector<std::vector<int>> sources(nbrs.size());
  auto add_kept = [&](std::vector<int>& from, int q) {
    if (kept[q] >= 0 && std::find(from.begin(), from.end(), q) == from.end()) from.push_back(q);
  };
  for (std::size_t f = 0; f < nbrs.size(); ++f) {
    if (kept[f] >= 0) {
      sources[f] = {static_cast<int>(f)};
      continue;
    }
    for (int q : nbrs[f]) add_kept(sources[f], q);
    if (sources[f].size() >= 2) continue;
    for (int q : nbrs[f]) {
      if (kept[q] >= 0) continue;
      for (int r : nbrs[q]) add_kept(sources[f], r);
    }
  }
  return sources;
}

/// Interpolation and lumped masses (PᵀMP lumped: a dropped particle's mass, area and drag
/// go in equal shares to the kept particles it is interpolated from).
void Interpolate(const ClothModel& fine, const std::vector<std::vector<int>>& sources,
                 MeshCoarsening& out) {
  const int nc = static_cast<int>(out.fine_index.size());
  ClothModelData& data = out.coarse;
  data.masses = Eigen::VectorXd::Zero(nc);
  data.areas = Eigen::VectorXd::Zero(nc);
  data.drag = Eigen::VectorXd::Zero(nc);
  out.interpolation_start.assign(1, 0);
  const bool has_drag = fine.drag().size() == fine.num_particles();
  for (int f = 0; f < fine.num_particles(); ++f) {
    for (int q : sources[f]) out.interpolation_from.push_back(out.kept[q]);
    const int first = out.interpolation_start.back();
    const int count = static_cast<int>(out.interpolation_from.size()) - first;
    for (int k = first; k < first + count; ++k) {
      const int c = out.interpolation_from[k];
      data.masses[c] += fine.masses()[f] / count;
      data.areas[c] += fine.areas()[f] / count;
      if (has_drag) data.drag[c] += fine.drag()[f] / count;
    }
    out.interpolation_start.push_back(first + count);
  }
}

/// Labels the pairs that do not turn at any dropped particle: shear when the two ends share a
/// neighbour through turning pairs (then they are a coarse cell's diagonal, that neighbour
/// one of its other corners: every such pair on a lattice, whatever its cells' aspect),
/// structural otherwise. On a triangle mesh two kept particles often face each other across
/// a dropped one with no coarse cell around them; called shear, they left the next coarsening,
/// which follows structural springs only, a level whose particles had none (docs/pyramid.md).
void LabelCellDiagonals(std::map<std::pair<int, int>, bool>& pairs, int num_coarse) {
  std::vector<std::vector<int>> turning(num_coarse);
  for (const auto& [pair, structural] : pairs) {
    if (!structural) continue;
    turning[pair.first].push_back(pair.second);
    turning[pair.second].push_back(pair.first);
  }
  for (std::vector<int>& around : turning) std::sort(around.begin(), around.end());
  std::vector<int> corners;
  for (auto& [pair, structural] : pairs) {
    if (structural) continue;
    const std::vector<int>& at_a = turning[pair.first];
    const std::vector<int>& at_b = turning[pair.second];
    corners.clear();
    std::set_intersection(at_a.begin(), at_a.end(), at_b.begin(), at_b.end(),
                          std::back_inserter(corners));
    structural = corners.empty();
  }
}

/// Coarse pairs: the kept particles a dropped particle is interpolated from, and the ends of
/// every structural spring between two dropped particles, which the Galerkin product PᵀAP
/// couples too (none on a lattice, many on meshes that cannot be two-coloured). A pair is
/// structural when some path between its ends turns at a dropped particle (angle below 135°:
/// a cell diagonal of the finer level), else as LabelCellDiagonals says — on a lattice,
/// exactly the rotated lattice's structural and shear springs, borders included.
std::map<std::pair<int, int>, bool> CoarsePairs(const ClothModel& fine,
                                                const std::vector<std::vector<int>>& nbrs,
                                                const std::vector<std::vector<int>>& sources,
                                                const std::vector<int>& kept, int num_coarse) {
  std::map<std::pair<int, int>, bool> pairs;
  const Points& x = fine.rest_positions();
  for (std::size_t f = 0; f < nbrs.size(); ++f) {
    if (kept[f] >= 0) continue;
    const std::vector<int>& from = sources[f];
    for (std::size_t i = 0; i < from.size(); ++i) {
      for (std::size_t j = i + 1; j < from.size(); ++j) {
        const int p = from[i], q = from[j];
        const int a = kept[p], b = kept[q];
        const Eigen::Vector3d to_p = (x.row(p) - x.row(f)).normalized();
        const Eigen::Vector3d to_q = (x.row(q) - x.row(f)).normalized();
        const bool turns = to_p.dot(to_q) > -0.7071;
        bool& structural = pairs.try_emplace({std::min(a, b), std::max(a, b)}, false).first->second;
        structural = structural || turns;
      }
    }
  }
  for (int p = 0; p < static_cast<int>(nbrs.size()); ++p) {
    if (kept[p] >= 0) continue;
    for (int q : nbrs[p]) {
      if (kept[q] >= 0 || q < p) continue;
      for (int r : sources[p]) {
        for (int t : sources[q]) {
          const int a = kept[r], b = kept[t];
          if (a != b) pairs.try_emplace({std::min(a, b), std::max(a, b)}, false);
        }
      }
    }
  }
  LabelCellDiagonals(pairs, num_coarse);
  return pairs;
}

/// Each coarse particle's share of the fine stretch/shear stiffness tensor: half of every
/// fine spring goes to each end, a dropped end's half shared like its mass.
std::vector<Tensor4> FineTensorShares(const ClothModel& fine, const MeshCoarsening& out) {
  std::vector<Tensor4> shares(out.fine_index.size(), Tensor4::Zero());
  for (const Spring& s : fine.springs()) {
    if (s.kind == SpringKind::kBending) continue;
    const Eigen::Vector3d d = fine.rest_positions().row(s.b) - fine.rest_positions().row(s.a);
    const Tensor4 half = 0.25 * s.stiffness * d.squaredNorm() * Quartic(d.normalized());
    for (int end : {s.a, s.b}) {
      const int first = out.interpolation_start[end], last = out.interpolation_start[end + 1];
      for (int k = first; k < last; ++k) shares[out.interpolation_from[k]] += half / (last - first);
    }
  }
  return shares;
}

/// Pairs of coarse springs leaving one particle in opposite directions (cosine below
/// −0.8): the continuation of one line of springs through that particle.
std::vector<std::pair<int, int>> OppositePairs(const ClothModelData& coarse,
                                               const std::vector<Spring>& springs) {
  std::vector<std::vector<int>> at(coarse.rest_positions.rows());
  for (std::size_t e = 0; e < springs.size(); ++e) {
    at[springs[e].a].push_back(static_cast<int>(e));
    at[springs[e].b].push_back(static_cast<int>(e));
  }
  std::vector<std::pair<int, int>> pairs;
  for (std::size_t m = 0; m < at.size(); ++m) {
    auto direction = [&](int e) {
      const int other = springs[e].a == static_cast<int>(m) ? springs[e].b : springs[e].a;
      return Eigen::Vector3d((coarse.rest_positions.row(other) - coarse.rest_positions.row(m))
                                 .transpose().normalized());
    };
    for (std::size_t i = 0; i < at[m].size(); ++i) {
      for (std::size_t j = i + 1; j < at[m].size(); ++j) {
        if (direction(at[m][i]).dot(direction(at[m][j])) < -0.8) {
          pairs.emplace_back(at[m][i], at[m][j]);
        }
      }
    }
  }
  return pairs;
}

/// Least-squares stiffnesses of the coarse stretch/shear springs: Σ over each coarse
/// particle of |its springs' tensor share − its fine share|². Per-particle sums leave
/// stiffnesses that alternate along a line of springs undetermined (+δ, −δ cancels at every
/// particle), so a smoothness term ties each spring to its continuation through a particle;
/// where the fine model is uniform the exact solution is uniform and pays nothing for it.
/// A tiny pull towards the mean fine stiffness keeps isolated springs finite; negative
/// results (possible on irregular meshes) are clamped to zero.
Eigen::VectorXd FitStiffness(const ClothModelData& coarse, const std::vector<Spring>& springs,
                             const std::vector<Tensor4>& shares, double mean_stiffness) {
  const int ns = static_cast<int>(springs.size());
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(15 * static_cast<int>(shares.size()));
  for (std::size_t c = 0; c < shares.size(); ++c) rhs.segment<15>(15 * c) = shares[c];
  for (int e = 0; e < ns; ++e) {
    const Eigen::Vector3d d =
        coarse.rest_positions.row(springs[e].b) - coarse.rest_positions.row(springs[e].a);
    const Tensor4 unit = 0.25 * d.squaredNorm() * Quartic(d.normalized());
    for (int end : {springs[e].a, springs[e].b}) {
      for (int k = 0; k < 15; ++k) entries.emplace_back(15 * end + k, e, unit[k]);
    }
  }
  Eigen::SparseMatrix<double> a(rhs.size(), ns);
  a.setFromTriplets(entries.begin(), entries.end());
  Eigen::SparseMatrix<double> normal = a.transpose() * a;
  const double scale = normal.diagonal().mean();
  const double smooth = scale, lambda = 1e-9 * scale;
  for (const auto& [e1, e2] : OppositePairs(coarse, springs)) {
    normal.coeffRef(e1, e1) += smooth;
    normal.coeffRef(e2, e2) += smooth;
    normal.coeffRef(e1, e2) -= smooth;
    normal.coeffRef(e2, e1) -= smooth;
  }
  Eigen::VectorXd b = a.transpose() * rhs;
  for (int e = 0; e < ns; ++e) {
    normal.coeffRef(e, e) += lambda;
    b[e] += lambda * mean_stiffness;
  }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  return solver.solve(b).cwiseMax(0.0);
}

/// Damping per unit stiffness of the fine springs of one family (c = τ·k holds per family).
double DampingRatio(const ClothModel& fine, bool bending) {
  double k = 0.0, c = 0.0;
  for (const Spring& s : fine.springs()) {
    if ((s.kind == SpringKind::kBending) != bending) continue;
    k += s.stiffness;
    c += s.damping;
  }
  return k > 0.0 ? c / k : 0.0;
}

void AddStretchShearSprings(const ClothModel& fine, const std::vector<std::vector<int>>& nbrs,
                            const std::vector<std::vector<int>>& sources, MeshCoarsening& out) {
  ClothModelData& data = out.coarse;
  std::vector<Spring> springs;
  const int num_coarse = static_cast<int>(out.fine_index.size());
  for (const auto& [pair, structural] : CoarsePairs(fine, nbrs, sources, out.kept, num_coarse)) {
    Spring s;
    s.a = pair.first;
    s.b = pair.second;
    s.kind = structural ? SpringKind::kStructural : SpringKind::kShear;
    s.rest_length = (data.rest_positions.row(s.b) - data.rest_positions.row(s.a)).norm();
    springs.push_back(s);
  }
  double sum = 0.0;
  int count = 0;
  for (const Spring& s : fine.springs()) {
    if (s.kind != SpringKind::kBending) sum += s.stiffness, ++count;
  }
  const Eigen::VectorXd k =
      FitStiffness(data, springs, FineTensorShares(fine, out), count ? sum / count : 0.0);
  const double tau = DampingRatio(fine, false);
  for (std::size_t e = 0; e < springs.size(); ++e) {
    if (k[e] <= 0.0) continue;
    springs[e].stiffness = k[e];
    springs[e].damping = tau * k[e];
    data.springs.push_back(springs[e]);
  }
}

/// Bending springs skip one coarse structural neighbour along the straightest line
/// (angle > 150°), with the fine rigidity B = kℓ²/4 averaged over the particles each end
/// stands for, and K = 4B/L² at the coarse length L.
void AddBendingSprings(const ClothModel& fine, MeshCoarsening& out) {
  ClothModelData& data = out.coarse;
  const int nc = static_cast<int>(out.fine_index.size());
  Eigen::VectorXd rigidity = Eigen::VectorXd::Zero(nc), weight = Eigen::VectorXd::Zero(nc);
  for (const Spring& s : fine.springs()) {
    if (s.kind != SpringKind::kBending) continue;
    const double b = s.stiffness * s.rest_length * s.rest_length / 4.0;
    for (int end : {s.a, s.b}) {
      const int first = out.interpolation_start[end], last = out.interpolation_start[end + 1];
      for (int k = first; k < last; ++k) {
        rigidity[out.interpolation_from[k]] += b;
        weight[out.interpolation_from[k]] += 1.0;
      }
    }
  }
  if (weight.sum() == 0.0) return;
  std::vector<std::vector<int>> structural(nc);
  for (const Spring& s : data.springs) {
    if (s.kind != SpringKind::kStructural) continue;
    structural[s.a].push_back(s.b);
    structural[s.b].push_back(s.a);
  }
  const double tau = DampingRatio(fine, true);
  // A pair already joined by a stretch or shear spring gets no bending spring beside it: on
  // an irregular mesh (the MakeHuman casual suit) the straightest line through a particle
  // can end at a particle two structural steps from the other end, and a model allows one
  // spring per pair.
  std::map<std::pair<int, int>, bool> added;
  for (const Spring& s : data.springs) added.emplace(std::minmax(s.a, s.b), true);
  for (int m = 0; m < nc; ++m) {
    const Eigen::Vector3d x = data.rest_positions.row(m).transpose();
    for (int a : structural[m]) {
      const Eigen::Vector3d da = (data.rest_positions.row(a).transpose() - x).normalized();
      int best = -1;
      double best_cos = std::cos(150.0 / 180.0 * 3.14159265358979);
      for (int b : structural[m]) {
        const double cosine = da.dot((data.rest_positions.row(b).transpose() - x).normalized());
        if (b != a && cosine < best_cos) best = b, best_cos = cosine;
      }
      if (best < 0 || !added.emplace(std::minmax(a, best), true).second) continue;
      const double b_mean = 0.5 * (rigidity[a] / std::max(1.0, weight[a]) +
                                   rigidity[best] / std::max(1.0, weight[best]));
      Spring s;
      s.a = std::min(a, best);
      s.b = std::max(a, best);
      s.kind = SpringKind::kBending;
      s.rest_length = (data.rest_positions.row(s.b) - data.rest_positions.row(s.a)).norm();
      s.stiffness = 4.0 * b_mean / (s.rest_length * s.rest_length);
      s.damping = tau * s.stiffness;
      if (s.stiffness > 0.0) data.springs.push_back(s);
    }
  }
}

}  // namespace

std::optional<MeshCoarsening> CoarsenMesh(const ClothModel& fine, int min_particles) {
  const std::vector<std::vector<int>> nbrs = StructuralNeighbours(fine);
  const std::vector<bool> selected = SelectKept(fine, nbrs);
  MeshCoarsening out;
  out.kept.assign(fine.num_particles(), -1);
  for (int p = 0; p < fine.num_particles(); ++p) {
    if (!selected[p]) continue;
    out.kept[p] = static_cast<int>(out.fine_index.size());
    out.fine_index.push_back(p);
  }
  const int nc = static_cast<int>(out.fine_index.size());
  if (nc < min_particles || 4 * nc > 3 * fine.num_particles()) return std::nullopt;

  ClothModelData& data = out.coarse;
  data.name = fine.name() + " (coarse)";
  data.rest_positions.resize(nc, 3);
  for (int c = 0; c < nc; ++c) data.rest_positions.row(c) = fine.rest_positions().row(out.fine_index[c]);
  for (int p : fine.pinned()) {
    if (out.kept[p] >= 0) data.pinned.push_back(out.kept[p]);
  }
  const std::vector<std::vector<int>> sources = Sources(nbrs, out.kept);
  Interpolate(fine, sources, out);
  AddStretchShearSprings(fine, nbrs, sources, out);
  AddBendingSprings(fine, out);
  return out;
}

}  // namespace costume::sim
