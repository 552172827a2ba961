#include "sim_core/collision/mesh_distance.h"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <mutex>
#include <utility>
#include <vector>

#include "sim_core/collision/dbvt_walk.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

btVector3 ToBullet(const Eigen::Vector3d& v) { return btVector3(v.x(), v.y(), v.z()); }
Eigen::Vector3d ToEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

btDbvtVolume TriangleBox(const Points& vertices, const Eigen::Vector3i& tri) {
  const Eigen::Vector3d a = vertices.row(tri[0]).transpose();
  const Eigen::Vector3d b = vertices.row(tri[1]).transpose();
  const Eigen::Vector3d c = vertices.row(tri[2]).transpose();
  return btDbvtVolume::FromMM(ToBullet(a.cwiseMin(b).cwiseMin(c)),
                              ToBullet(a.cwiseMax(b).cwiseMax(c)));
}

// Squared distance from `p` to the box `volume` [m²] (0 inside).
double SquaredBoxDistance(const btDbvtVolume& volume, const Eigen::Vector3d& p) {
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double below = volume.Mins()[k] - p[k];
    const double above = p[k] - volume.Maxs()[k];
    const double gap = std::max({below, above, 0.0});
    sum += gap * gap;
  }
  return sum;
}

int LeafTriangle(const btDbvtNode* leaf) {
  return static_cast<int>(reinterpret_cast<std::intptr_t>(leaf->data));
}

const std::vector<Eigen::Vector3i>& Validated(const std::string& name, const Points& vertices,
                                               const std::vector<Eigen::Vector3i>& triangles) {
  const std::string where = "mesh '" + name + "'";
  if (triangles.empty()) throw InputError(where + ": has no triangles (need a closed mesh)");
  for (Eigen::Index v = 0; v < vertices.rows(); ++v) {
    if (!vertices.row(v).allFinite()) {
      throw InputError(where + ": vertex " + std::to_string(v) +
                       " has a non-finite position (allowed: finite coordinates in m)");
    }
  }
  const int n = static_cast<int>(vertices.rows());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (triangles[t].minCoeff() < 0 || triangles[t].maxCoeff() >= n) {
      throw InputError(where + ": triangle " + std::to_string(t) +
                       " has a vertex index out of range (allowed 0.." + std::to_string(n - 1) +
                       ")");
    }
  }
  return triangles;
}

/// Appends the nodes under `node` to `order`, each after its children. Refit then sets the
/// boxes in one pass down that list: a leaf's to its triangle's, an internal node's to its
/// children's union. The trees keep the structure they were built with, which skinning
/// deforms smoothly; reinserting every leaf (btDbvt::update) made an update of MakeHuman's
/// 26 k triangles take 14.7 ms, against 4.3 ms recursing down the tree; the list takes a
/// sixth to a third off an arm-spread search, which refits once per pose (docs/assets.md).
void AppendBottomUp(btDbvtNode* node, std::vector<btDbvtNode*>& order) {
  if (!node->isleaf()) {
    AppendBottomUp(node->childs[0], order);
    AppendBottomUp(node->childs[1], order);
  }
  order.push_back(node);
}

/// A copy of `from` in the empty `to`, node for node; false (`to` then unusable) when the
/// copy turns out not to be one. Bullet's clone (3.24) walks the tree with a stack and gives
/// each node's children the slots of their stack positions' parity: the children of a node
/// popped from an odd position come out swapped. They are put back by the same walk, since
/// the order in which queries visit children decides between exactly equally near
/// triangles; the walk also checks every node's box and every leaf's triangle, so a Bullet
/// that clones otherwise is caught, not trusted. (Its clone also calls the leaf callback it
/// is given without checking for none.)
bool CloneTree(const btDbvt& from, btDbvt& to) {
  btDbvt::IClone keep_leaves;  // leaves carry a triangle index: nothing to copy
  from.clone(to, &keep_leaves);
  if (from.m_root == nullptr) return to.m_root == nullptr;
  std::vector<std::pair<const btDbvtNode*, btDbvtNode*>> stack{{from.m_root, to.m_root}};
  while (!stack.empty()) {
    const std::size_t position = stack.size() - 1;
    const auto [original, copy] = stack.back();
    stack.pop_back();
    if (copy == nullptr || copy->isleaf() != original->isleaf() ||
        NotEqual(copy->volume, original->volume)) {
      return false;
    }
    if (original->isleaf()) {
      if (copy->data != original->data) return false;
      continue;
    }
    if (position % 2 == 1) std::swap(copy->childs[0], copy->childs[1]);
    stack.emplace_back(original->childs[0], copy->childs[0]);
    stack.emplace_back(original->childs[1], copy->childs[1]);
  }
  return true;
}

/// The trees of the last large meshes built, cloned when the same mesh (the same vertices and
/// triangles, compared in full) is built again: a scene's build makes the avatar's rest body
/// for the garments' fit, the arm-spread search and the superquadric collider, and Bullet's
/// optimizeTopDown takes 180 ms of each for MakeHuman's 26 k triangles, a clone a few. The
/// trees' structure depends only on the mesh, and a clone has the same, so it answers every
/// query as a build would, bit for bit. Process-wide, behind a mutex; two meshes of about
/// 5 MB each.
class TreeStore {
 public:
  /// Meshes smaller than this build in a few milliseconds and are not kept [triangles].
  static constexpr std::size_t kMinTriangles = 2000;

  static TreeStore& Instance() {
    static TreeStore store;
    return store;
  }

  /// Fills `pieces` (empty) with clones of the trees kept for this mesh; false when none are.
  bool CloneInto(const Points& vertices, const std::vector<Eigen::Vector3i>& triangles,
                 std::vector<std::unique_ptr<btDbvt>>& pieces) {
    if (triangles.size() < kMinTriangles) return false;
    const std::lock_guard lock(mutex_);
    for (const Entry& entry : entries_) {
      if (entry.triangles != triangles || entry.vertices != vertices) continue;
      for (const auto& tree : entry.pieces) {
        pieces.push_back(std::make_unique<btDbvt>());
        if (!CloneTree(*tree, *pieces.back())) {
          pieces.clear();
          return false;
        }
      }
      return true;
    }
    return false;
  }

  /// Keeps clones of `pieces`, built for this mesh, forgetting the oldest beyond kKept.
  void Keep(const Points& vertices, const std::vector<Eigen::Vector3i>& triangles,
            const std::vector<std::unique_ptr<btDbvt>>& pieces) {
    if (triangles.size() < kMinTriangles) return;
    Entry entry{vertices, triangles, {}};
    for (const auto& tree : pieces) {
      entry.pieces.push_back(std::make_unique<btDbvt>());
      if (!CloneTree(*tree, *entry.pieces.back())) return;
    }
    const std::lock_guard lock(mutex_);
    entries_.push_front(std::move(entry));
    if (entries_.size() > kKept) entries_.pop_back();
  }

 private:
  static constexpr std::size_t kKept = 2;
  struct Entry {
    Points vertices;
    std::vector<Eigen::Vector3i> triangles;
    std::vector<std::unique_ptr<btDbvt>> pieces;
  };
  std::mutex mutex_;
  std::deque<Entry> entries_;
};

}  // namespace

struct MeshDistance::Trees {
  /// One tree per piece, so each piece's closest point (and thus its sign) is found.
  std::vector<std::unique_ptr<btDbvt>> pieces;
  /// Every piece's nodes, each after its children: the order Refit sets their boxes in.
  std::vector<btDbvtNode*> bottom_up;
  /// Traversal scratch, sized for the worst case at construction.
  mutable std::vector<const btDbvtNode*> stack;
};

MeshDistance::MeshDistance(std::string name, const Points& vertices,
                           std::vector<Eigen::Vector3i> triangles)
    : name_(std::move(name)),
      num_vertices_(static_cast<int>(vertices.rows())),
      vertices_(vertices),
      normals_(num_vertices_, Validated(name_, vertices, triangles)),
      trees_(std::make_unique<Trees>()) {
  if (normals_.num_open_edges() > 0) {
    throw InputError("mesh '" + name_ + "': not closed and consistently oriented: " +
                     normals_.first_open_edge() + " (" +
                     std::to_string(normals_.num_open_edges()) +
                     " such edges; allowed: every edge used by two triangles, once each way)");
  }
  reused_trees_ = TreeStore::Instance().CloneInto(vertices_, normals_.triangles(), trees_->pieces);
  if (!reused_trees_) BuildTrees();
  for (auto& tree : trees_->pieces) {
    if (tree->m_root != nullptr) AppendBottomUp(tree->m_root, trees_->bottom_up);
  }
  // A binary tree's depth-first stack never holds more than one node per leaf plus one.
  trees_->stack.reserve(num_triangles() + 2);
  UpdateNormals();
}

MeshDistance::~MeshDistance() = default;

void MeshDistance::BuildTrees() {
  trees_->pieces.resize(num_pieces());
  for (auto& tree : trees_->pieces) tree = std::make_unique<btDbvt>();
  for (int t = 0; t < num_triangles(); ++t) {
    trees_->pieces[normals_.piece_of(t)]->insert(
        TriangleBox(vertices_, normals_.triangles()[t]),
        reinterpret_cast<void*>(static_cast<std::intptr_t>(t)));
  }
  for (auto& tree : trees_->pieces) tree->optimizeTopDown();
  TreeStore::Instance().Keep(vertices_, normals_.triangles(), trees_->pieces);
}

bool MeshDistance::Update(const Points& vertices) {
  if (vertices.rows() != num_vertices_) return false;
  vertices_ = vertices;  // same size: copies into the existing storage
  Refit(vertices_);
  return true;
}

void MeshDistance::Refit(const Points& vertices) {
  // Bullet allocates its nodes one by one, so the list visits them scattered over memory
  // the size of the caches or more (MakeHuman's 52 k nodes: about 4 MB): fetching a few
  // ahead lets their loads overlap instead of each waiting in turn.
  constexpr std::size_t kAhead = 16;
  const std::vector<btDbvtNode*>& order = trees_->bottom_up;
  for (std::size_t i = 0; i < order.size(); ++i) {
    if (i + kAhead < order.size()) __builtin_prefetch(order[i + kAhead], 1);
    btDbvtNode* node = order[i];
    if (node->isleaf()) {
      node->volume = TriangleBox(vertices, normals_.triangles()[LeafTriangle(node)]);
    } else {
      Merge(node->childs[0]->volume, node->childs[1]->volume, node->volume);
    }
  }
  normals_current_ = false;
}

void MeshDistance::UpdateNormals() const {
  if (normals_current_) return;
  // Vertex pseudonormals (three arc tangents a triangle, most of the cost) are computed
  // for the few closest points that land on a vertex.
  normals_.Update(vertices_, /*vertex_normals=*/false);
  normals_current_ = true;
}

void MeshDistance::NearestInPiece(int piece, const Eigen::Vector3d& point, double max_radius,
                                  SurfaceDistance& best) const {
  double best_squared = max_radius * max_radius;
  int best_triangle = -1;
  TrianglePoint best_point;
  WalkTree(
      *trees_->pieces[piece], trees_->stack,
      [&](const btDbvtNode* node) {
        return SquaredBoxDistance(node->volume, point) <= best_squared;
      },
      // The nearer child first, so it shrinks the radius sooner.
      [&](const btDbvtNode* node) {
        return SquaredBoxDistance(node->childs[0]->volume, point) <
                       SquaredBoxDistance(node->childs[1]->volume, point)
                   ? 0
                   : 1;
      },
      [&](const btDbvtNode* node) {
        const int t = LeafTriangle(node);
        const Eigen::Vector3i& tri = normals_.triangles()[t];
        const TrianglePoint closest = ClosestPointOnTriangle(
            point, vertices_.row(tri[0]).transpose(), vertices_.row(tri[1]).transpose(),
            vertices_.row(tri[2]).transpose());
        const double squared = (point - closest.point).squaredNorm();
        if (squared <= best_squared) {
          best_squared = squared;
          best_triangle = t;
          best_point = closest;
        }
        return true;
      });
  if (best_triangle < 0) return;
  const SurfaceSide side =
      SideOf(point, best_point.point, normals_.Of(best_triangle, best_point.feature, vertices_));
  if (side.signed_distance >= best.signed_distance) return;
  best.signed_distance = side.signed_distance;
  best.closest_point = best_point.point;
  best.normal = side.normal;
  best.triangle = best_triangle;
  best.feature = best_point.feature;
  best.barycentric = best_point.barycentric;
}

SurfaceDistance MeshDistance::Query(const Eigen::Vector3d& point, double max_radius) const {
  SurfaceDistance best;
  if (!(max_radius >= 0.0) || !point.allFinite()) return best;
  UpdateNormals();
  for (int piece = 0; piece < num_pieces(); ++piece) {
    NearestInPiece(piece, point, max_radius, best);
  }
  return best;
}

bool MeshDistance::WindingInPiece(int piece, const Eigen::Vector3d& point,
                                  const Eigen::Vector3d& direction, int& winding) const {
  winding = 0;
  const Eigen::Vector3d inverse = direction.cwiseInverse();
  return WalkTree(
      *trees_->pieces[piece], trees_->stack,
      [&](const btDbvtNode* node) {
        return RayMeetsBox(ToEigen(node->volume.Mins()), ToEigen(node->volume.Maxs()), point,
                           inverse);
      },
      [](const btDbvtNode*) { return 1; },  // a count: any order
      [&](const btDbvtNode* node) {
        const Eigen::Vector3i& tri = normals_.triangles()[LeafTriangle(node)];
        switch (RayCrossing(point, direction, vertices_.row(tri[0]).transpose(),
                            vertices_.row(tri[1]).transpose(),
                            vertices_.row(tri[2]).transpose())) {
          case Crossing::kNone: return true;
          case Crossing::kExit: ++winding; return true;
          case Crossing::kEntry: --winding; return true;
          case Crossing::kUncertain: return false;
        }
        return true;
      });
}

bool MeshDistance::Inside(const Eigen::Vector3d& point, const std::vector<char>* pieces) const {
  if (!point.allFinite()) return false;
  for (int piece = 0; piece < num_pieces(); ++piece) {
    if (pieces && !(*pieces)[piece]) continue;
    int winding = 0;
    bool counted = false;
    for (const Eigen::Vector3d& direction : WindingRayDirections()) {
      counted = WindingInPiece(piece, point, direction, winding);
      if (counted) break;
    }
    // Every ray grazing an edge or a plane: the point lies on the surface, not inside by
    // any measurable depth.
    if (counted && winding >= 1) return true;
  }
  return false;
}

double MeshDistance::PenetrationDepth(const Eigen::Vector3d& point, double max_radius) const {
  const double distance = SignedDistance(point, max_radius);
  if (!std::isfinite(distance) || !Inside(point)) return 0.0;
  return std::abs(distance);
}

void MeshDistance::PenetrationDepths(const Points& points, double max_radius,
                                     std::vector<double>& depths) const {
  depths.resize(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    depths[i] = PenetrationDepth(points.row(i).transpose(), max_radius);
  }
}

PenetrationStats MeshDistance::MeasurePenetration(const Points& points,
                                                  double max_radius) const {
  std::vector<double> depths;
  PenetrationDepths(points, max_radius, depths);
  PenetrationStats stats;
  stats.num_points = static_cast<int>(points.rows());
  std::vector<double> inside;
  for (double depth : depths) {
    if (depth > 0.0) inside.push_back(depth);
  }
  stats.num_inside = static_cast<int>(inside.size());
  if (inside.empty()) return stats;
  std::sort(inside.begin(), inside.end());
  stats.max_depth = inside.back();
  // Nearest rank: the smallest depth at or above 99% of the inside points.
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.99 * inside.size()));
  stats.p99_depth = inside[std::max<std::size_t>(rank, 1) - 1];
  return stats;
}

}  // namespace costume::sim
