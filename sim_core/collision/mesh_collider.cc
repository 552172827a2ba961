#include "sim_core/collision/mesh_collider.h"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include "sim_core/collision/dbvt_walk.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Added to the triangles' spread around their cells [m], so that rounding in the cell
/// bounds can only make them more conservative.
constexpr double kRoundingSlack = 1e-12;
/// How far beyond its reach a query walks the region trees [m], only to bound the distance
/// to the pieces it finds nothing of: a particle moving less than this keeps them out of
/// reach without walking them again.
constexpr double kBoundExtension = 0.04;

/// Sorts [first, first + count) by `less`, keeping equal elements in order, without
/// allocating (the lists are short).
template <class T, class Less>
void InsertionSort(T* first, int count, Less less) {
  for (int i = 1; i < count; ++i) {
    const T moving = first[i];
    int j = i;
    for (; j > 0 && less(moving, first[j - 1]); --j) first[j] = first[j - 1];
    first[j] = moving;
  }
}

/// Triangles of each region.
using RegionList = std::vector<std::vector<int>>;

void ValidateInputs(const Avatar* avatar, const BodyCollisionSettings& settings,
                    const MeshCollisionOptions& options) {
  if (avatar == nullptr) throw InputError("mesh collider: no avatar given");
  const std::string where = "mesh collider of avatar '" + avatar->name() + "'";
  if (avatar->triangles().empty()) throw InputError(where + ": the avatar has no triangles");
  RequireNonNegative(where + " settings.thickness", settings.thickness, "m");
  RequireNonNegative(where + " settings.friction", settings.friction, "");
  if (options.region_size < 1 || options.region_size > 256) {
    throw InputError(where + ": options.region_size is " + std::to_string(options.region_size) +
                     " (allowed 1..256)");
  }
  if (!(options.flatness_angle >= 0.0 && options.flatness_angle < kPi / 2)) {
    throw InputError(where + ": options.flatness_angle is " +
                     FormatValue(options.flatness_angle) + " rad (allowed [0, pi/2))");
  }
  if (options.max_merge_levels < 0 || options.max_merge_levels > 16) {
    throw InputError(where + ": options.max_merge_levels is " +
                     std::to_string(options.max_merge_levels) + " (allowed 0..16)");
  }
  RequirePositive(where + " options.max_penetration", options.max_penetration, "m");
  if (options.cloth_region_size < 1 || options.cloth_region_size > 256) {
    throw InputError(where + ": options.cloth_region_size is " +
                     std::to_string(options.cloth_region_size) + " (allowed 1..256)");
  }
  if (options.cloth_cone_period < 1 || options.cloth_cone_period > 64) {
    throw InputError(where + ": options.cloth_cone_period is " +
                     std::to_string(options.cloth_cone_period) + " (allowed 1..64)");
  }
  if (!(options.cloth_flatness_angle >= 0.0 && options.cloth_flatness_angle < kPi / 2)) {
    throw InputError(where + ": options.cloth_flatness_angle is " +
                     FormatValue(options.cloth_flatness_angle) + " rad (allowed [0, pi/2))");
  }
}

/// Regions of up to `target` triangles, each grown breadth first over edge adjacency from
/// the lowest unassigned triangle, so they are compact patches.
RegionList GrowBaseRegions(const SurfacePseudonormals& mesh, int target) {
  std::vector<int> owner(mesh.num_triangles(), -1);
  RegionList regions;
  std::vector<int> queue;
  for (int seed = 0; seed < mesh.num_triangles(); ++seed) {
    if (owner[seed] >= 0) continue;
    const int id = static_cast<int>(regions.size());
    regions.emplace_back();
    queue.assign(1, seed);
    owner[seed] = id;
    std::size_t head = 0;
    while (head < queue.size() && static_cast<int>(regions[id].size()) < target) {
      const int t = queue[head++];
      regions[id].push_back(t);
      for (int k = 0; k < 3; ++k) {
        const int n = mesh.neighbour(t, k);
        if (n >= 0 && owner[n] < 0) {
          owner[n] = id;
          queue.push_back(n);
        }
      }
    }
    for (std::size_t i = head; i < queue.size(); ++i) owner[queue[i]] = -1;  // not taken
  }
  return regions;
}

/// Half-angle [rad] of the cone around the area-weighted mean normal of `a` ∪ `b` that
/// holds every (non-degenerate) triangle normal of them: Provot's normal-cone test.
double ConeHalfAngle(const SurfacePseudonormals& mesh, const std::vector<int>& a,
                     const std::vector<int>& b) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto* list : {&a, &b}) {
    for (int t : *list) sum += mesh.double_area(t) * mesh.face_normal(t);
  }
  if (!(sum.norm() > 0.0)) return kPi;
  const Eigen::Vector3d axis = sum.normalized();
  double min_cos = 1.0;
  for (const auto* list : {&a, &b}) {
    for (int t : *list) {
      if (mesh.double_area(t) > 0.0) min_cos = std::min(min_cos, axis.dot(mesh.face_normal(t)));
    }
  }
  return std::acos(std::clamp(min_cos, -1.0, 1.0));
}

/// Regions sharing an edge with each region, ascending.
std::vector<std::vector<int>> RegionAdjacency(const SurfacePseudonormals& mesh,
                                              const RegionList& regions) {
  std::vector<int> owner(mesh.num_triangles(), -1);
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (int t : regions[r]) owner[t] = static_cast<int>(r);
  }
  std::vector<std::vector<int>> adjacency(regions.size());
  for (int t = 0; t < mesh.num_triangles(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int n = mesh.neighbour(t, k);
      if (n >= 0 && owner[n] != owner[t]) adjacency[owner[t]].push_back(owner[n]);
    }
  }
  for (auto& list : adjacency) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  return adjacency;
}

/// One quadtree-like level: each region not yet taken joins up to three of its untaken
/// neighbours while the union stays within the flatness cone. Returns whether any merged.
bool MergeLevel(const SurfacePseudonormals& mesh, double flatness_angle, RegionList& regions) {
  const auto adjacency = RegionAdjacency(mesh, regions);
  std::vector<char> taken(regions.size(), 0);
  RegionList merged;
  bool any = false;
  for (std::size_t r = 0; r < regions.size(); ++r) {
    if (taken[r]) continue;
    taken[r] = 1;
    std::vector<int> group = regions[r];
    int members = 1;
    for (int n : adjacency[r]) {
      if (members == 4) break;
      if (taken[n] || ConeHalfAngle(mesh, group, regions[n]) > flatness_angle) continue;
      group.insert(group.end(), regions[n].begin(), regions[n].end());
      taken[n] = 1;
      ++members;
    }
    any = any || members > 1;
    merged.push_back(std::move(group));
  }
  regions = std::move(merged);
  return any;
}

btVector3 ToBullet(const Eigen::Vector3d& v) { return btVector3(v.x(), v.y(), v.z()); }
Eigen::Vector3d ToEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

/// Index of the grid cell holding coordinate `x` along one axis, clamped to the grid.
int CellIndex(double x, double origin, double size, int count) {
  const double cell = std::floor((x - origin) / size);
  if (!(cell >= 0.0)) return 0;  // also NaN
  return cell >= count ? count - 1 : static_cast<int>(cell);
}

}  // namespace

/// One region and its plane grid, refitted every frame.
struct MeshColliderRegion {
  /// Its triangles: slots [first, first + count) of MeshColliderRegions::triangles
  /// (grouped by region)
  /// and of MeshColliderRegions::cell_triangles (by region, then by cell).
  int first = 0;
  int count = 0;
  /// Its vertices: slots [first_vertex, first_vertex + num_vertices) of
  /// MeshColliderRegions::vertices, each projected once per frame.
  int first_vertex = 0;
  int num_vertices = 0;
  /// Its grid: cells_u × cells_v cells, whose start offsets (relative to `first`) are
  /// MeshColliderRegions::cell_start[cell_first + cell], plus one past the last cell.
  int cell_first = 0;
  int cells_u = 1;
  int cells_v = 1;
  btDbvtNode* leaf = nullptr;
  /// The connected piece of the body its triangles belong to (regions grow and merge over
  /// shared edges, so all of them lie in one piece).
  int piece = 0;
  /// Mean plane frame: unit normal axis and two tangents [-].
  Eigen::Vector3d axis = Eigen::Vector3d::UnitY();
  Eigen::Vector3d tangent_u = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d tangent_v = Eigen::Vector3d::UnitX();
  /// Extent along the axis (the slab) and the grid's origin and cell sizes [m].
  double w_min = 0.0, w_max = 0.0;
  double u_min = 0.0, u_max = 0.0, v_min = 0.0, v_max = 0.0;
  double cell_size_u = 1.0, cell_size_v = 1.0;
  /// Largest distance, along u and along v, of a triangle's corner from its centroid [m]:
  /// a triangle within distance r of a point has its centroid within r + spread of it.
  double spread_u = 0.0, spread_v = 0.0;
  /// Box of its vertices [m].
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero(), box_max = Eigen::Vector3d::Zero();
  /// Lazy refit: whether the fields above are of an older pose than the collider's
  /// vertices, and a bound on how far its vertices have moved since they were fitted [m].
  bool stale = false;
  double travel = 0.0;
};

/// A triangle's corners and box [m], copied in grid order at every refit so the search
/// reads one contiguous record per triangle instead of three scattered vertex rows.
struct PackedTriangle {
  Eigen::Vector3d a, b, c;
  Eigen::Vector3d box_min, box_max;
  /// Unit normal [-] (zero for a degenerate triangle): |normal·(p − a)| is the distance to
  /// its plane, a lower bound of the distance to it.
  Eigen::Vector3d normal;
};

/// A box in a region's plane frame: along tangent_u, tangent_v and the axis [m].
struct FrameBox {
  double u_lo = kInf, u_hi = -kInf, v_lo = kInf, v_hi = -kInf, w_lo = kInf, w_hi = -kInf;

  void Add(const FrameBox& other) {
    u_lo = std::min(u_lo, other.u_lo);
    u_hi = std::max(u_hi, other.u_hi);
    v_lo = std::min(v_lo, other.v_lo);
    v_hi = std::max(v_hi, other.v_hi);
    w_lo = std::min(w_lo, other.w_lo);
    w_hi = std::max(w_hi, other.w_hi);
  }
};

/// A body region met by the current query, and the squared distance [m²] from the query
/// point to its box: a lower bound on the distance to any of its triangles.
struct RegionCandidate {
  int region = 0;
  double squared_distance = 0.0;
};

/// A piece to search and the lower bound on its signed distance now [m].
struct PieceBound {
  int piece = 0;
  double bound = 0.0;
};

/// What the current query did with a piece.
enum PieceState : char { kSearched, kSkipped, kOutOfReach };

struct MeshColliderRegions {
  std::vector<MeshColliderRegion> data;
  std::vector<int> triangles;
  std::vector<int> cell_start;
  /// Per cell (indexed as cell_start), the frame box of its triangles; empty when it has
  /// none. Its distance from a point bounds the distance to any of them from below.
  std::vector<FrameBox> cell_box;
  std::vector<int> cell_triangles;
  /// The triangles of `cell_triangles`, slot for slot.
  std::vector<PackedTriangle> packed;
  /// Per slot of `triangles`: the centroid's plane coordinates, its frame box and its cell
  /// (scratch).
  std::vector<double> centroid_u, centroid_v;
  std::vector<FrameBox> triangle_box;
  /// The vertices of each region (grouped by region), and per slot of `triangles` its
  /// corners as indices into its region's vertices.
  std::vector<int> vertices;
  std::vector<Eigen::Vector3i> local_corners;
  /// Projection scratch: a region's vertices in its plane frame [m].
  std::vector<double> project_u, project_v, project_w;
  std::vector<int> triangle_cell;
  std::vector<int> cursor;  // counting-sort scratch, as long as the largest grid
  /// One tree of region boxes per piece of the body, so that each piece is walked with
  /// its own search radius.
  std::vector<std::unique_ptr<btDbvt>> trees;
  std::vector<const btDbvtNode*> stack;
  /// Body regions (tree leaves) overlapping the current cloth node's box, in depth-first
  /// order; below them each deeper cloth node's share, one list per depth (sized by
  /// SetCloth: cloth depth + 1 lists of up to all leaves).
  std::vector<const btDbvtNode*> candidates;
  /// The regions of the current query, nearest box first (as long as `data`).
  std::vector<RegionCandidate> near;
  /// Per piece of the current query: the squared search radius [m²] (the extended reach
  /// until a triangle is found, then the distance to the nearest one: the radius shrinks),
  /// that triangle (−1: none yet) and its closest point; the pieces searched.
  std::vector<double> best_squared;
  std::vector<int> best_triangle;
  std::vector<TrianglePoint> best_point;
  std::vector<int> touched;
  /// Per piece of the current query: its signed distance [m] once resolved, whether that
  /// is within reach, and what the query did with it.
  std::vector<double> piece_distance;
  std::vector<char> in_reach;
  /// A lower bound on the distance [m] of a searched piece in which nothing was found.
  std::vector<double> unfound_bound;
  std::vector<PieceState> piece_state;
  /// The lowest signed distance within reach resolved so far [m].
  double lowest = 0.0;
  /// The pieces to search, in order.
  std::vector<PieceBound> order;
  /// What a lazy refit reads: the collider's surface and vertices (MeshCollider::normals_,
  /// vertices_).
  const SurfacePseudonormals* mesh = nullptr;
  const Points* skin = nullptr;
};

namespace {

/// Recomputes a region's plane frame, extents, centroids and box for `vertices`.
void ProjectRegion(const SurfacePseudonormals& mesh, const Points& vertices,
                   MeshColliderRegions& regions, MeshColliderRegion& region);
void IndexRegionVertices(const SurfacePseudonormals& mesh, int num_vertices,
                         MeshColliderRegions& regions);

}  // namespace

namespace {

/// About two triangles per cell, the cells shaped after the region's current extent.
void SizeGrid(MeshColliderRegion& region) {
  const int target = std::max(1, region.count / 2);
  const double extent_u = std::max(region.u_max - region.u_min, 1e-9);
  const double extent_v = std::max(region.v_max - region.v_min, 1e-9);
  region.cells_u = std::clamp(
      static_cast<int>(std::lround(std::sqrt(target * extent_u / extent_v))), 1, target);
  region.cells_v =
      std::clamp(static_cast<int>(std::lround(double(target) / region.cells_u)), 1, target);
}

}  // namespace

MeshCollider::MeshCollider(std::shared_ptr<const Avatar> avatar,
                           const BodyCollisionSettings& settings,
                           const MeshCollisionOptions& options)
    : avatar_((ValidateInputs(avatar.get(), settings, options), std::move(avatar))),
      settings_(settings),
      options_(options),
      normals_(avatar_->num_vertices(), avatar_->triangles()),
      vertices_(avatar_->rest_vertices()),
      vertex_velocities_(Points::Zero(avatar_->num_vertices(), 3)),
      regions_(std::make_unique<MeshColliderRegions>()) {
  normals_.Update(vertices_);
  RegionList list = GrowBaseRegions(normals_, options_.region_size * options_.region_size);
  num_base_regions_ = static_cast<int>(list.size());
  for (int level = 0; options_.adaptive && level < options_.max_merge_levels; ++level) {
    if (!MergeLevel(normals_, options_.flatness_angle, list)) break;
  }
  MeshColliderRegions& r = *regions_;
  const int num_triangles = normals_.num_triangles();
  r.triangles.reserve(num_triangles);
  r.data.resize(list.size());
  for (std::size_t i = 0; i < list.size(); ++i) {
    r.data[i].first = static_cast<int>(r.triangles.size());
    r.data[i].count = static_cast<int>(list[i].size());
    r.data[i].piece = normals_.piece_of(list[i].front());
    r.triangles.insert(r.triangles.end(), list[i].begin(), list[i].end());
  }
  r.cell_triangles.assign(num_triangles, 0);
  r.packed.resize(num_triangles);
  r.centroid_u.assign(num_triangles, 0.0);
  r.centroid_v.assign(num_triangles, 0.0);
  r.triangle_box.assign(num_triangles, FrameBox{});
  IndexRegionVertices(normals_, avatar_->num_vertices(), r);
  r.trees.resize(normals_.num_pieces());
  for (auto& tree : r.trees) tree = std::make_unique<btDbvt>();
  r.triangle_cell.assign(num_triangles, 0);
  // Grids sized on the rest pose, kept as the skin moves.
  int max_cells = 1;
  for (MeshColliderRegion& region : r.data) {
    ProjectRegion(normals_, vertices_, r, region);
    SizeGrid(region);
    region.cell_first = static_cast<int>(r.cell_start.size());
    r.cell_start.resize(r.cell_start.size() + region.cells_u * region.cells_v + 1, 0);
    r.cell_box.resize(r.cell_start.size());
    max_cells = std::max(max_cells, region.cells_u * region.cells_v);
    region.leaf = r.trees[region.piece]->insert(
        btDbvtVolume::FromMM(ToBullet(region.box_min), ToBullet(region.box_max)),
        reinterpret_cast<void*>(static_cast<std::intptr_t>(&region - r.data.data())));
  }
  r.cursor.assign(max_cells, 0);
  for (auto& tree : r.trees) tree->optimizeTopDown();
  r.stack.reserve(r.data.size() + 2);
  r.candidates.resize(r.data.size());
  r.near.resize(r.data.size());
  r.best_squared.assign(normals_.num_pieces(), kInf);
  r.best_triangle.assign(normals_.num_pieces(), -1);
  r.best_point.assign(normals_.num_pieces(), TrianglePoint{});
  r.in_reach.assign(normals_.num_pieces(), 0);
  r.unfound_bound.assign(normals_.num_pieces(), 0.0);
  r.piece_distance.assign(normals_.num_pieces(), kInf);
  r.piece_state.assign(normals_.num_pieces(), kSearched);
  r.order.resize(normals_.num_pieces());
  piece_travel_.assign(normals_.num_pieces(), 0.0);
  piece_step_.assign(normals_.num_pieces(), 0.0);
  piece_speed_.assign(normals_.num_pieces(), 0.0);
  vertex_step_.assign(avatar_->num_vertices(), 0.0);
  piece_closed_.assign(normals_.num_pieces(), 1);
  for (int t = 0; t < num_triangles; ++t) {
    for (int k = 0; k < 3; ++k) {
      if (normals_.neighbour(t, k) < 0) piece_closed_[normals_.piece_of(t)] = 0;
    }
  }
  r.touched.reserve(normals_.num_pieces());
  r.mesh = &normals_;
  r.skin = &vertices_;
  Refit(/*all=*/true);
}

MeshCollider::~MeshCollider() = default;

void MeshCollider::SetCloth(const ClothModel& cloth) {
  cloth_ = std::make_unique<ClothRegions>(cloth, options_.cloth_region_size);
  const std::size_t n = static_cast<std::size_t>(cloth.num_particles());
  half_extents_.assign(n, -1.0);
  reaches_.assign(n, 0.0);
  regions_->candidates.resize((cloth_->max_depth() + 1) * regions_->data.size());
  particle_contacts_.assign(n, Contact{});
  has_contact_.assign(n, 0);
  SizeMemory(cloth.num_particles());
}

void MeshCollider::SizeMemory(Eigen::Index n) {
  if (near_piece_.size() != static_cast<std::size_t>(n)) near_piece_.assign(n, -1);
  if (!UsesMemory() || memory_.size() == static_cast<std::size_t>(normals_.num_pieces() * n)) {
    return;
  }
  memory_.assign(normals_.num_pieces() * n, PieceMemory{});  // nothing known
  anchors_.setZero(n, 3);
}

bool MeshCollider::UsesMemory() const { return normals_.num_pieces() <= kMaxRememberedPieces; }

int MeshCollider::MemoryOf(int particle) const { return UsesMemory() ? particle : -1; }

int MeshCollider::num_regions() const { return static_cast<int>(regions_->data.size()); }

int MeshCollider::num_stale_regions() const {
  int stale = 0;
  for (const MeshColliderRegion& region : regions_->data) stale += region.stale ? 1 : 0;
  return stale;
}

namespace {

void ProjectRegion(const SurfacePseudonormals& mesh, const Points& vertices,
                   MeshColliderRegions& regions, MeshColliderRegion& region) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int j = region.first; j < region.first + region.count; ++j) {
    const int t = regions.triangles[j];
    sum += mesh.double_area(t) * mesh.face_normal(t);
  }
  // A closed region (normals summing to zero) keeps its last axis: any axis is correct,
  // only less effective.
  if (sum.norm() > 0.0) region.axis = sum.normalized();
  region.tangent_u = region.axis.unitOrthogonal();
  region.tangent_v = region.axis.cross(region.tangent_u);
  // Each vertex once (a vertex has about six triangles).
  double* pu = regions.project_u.data();
  double* pv = regions.project_v.data();
  double* pw = regions.project_w.data();
  region.box_min.setConstant(kInf);
  region.box_max.setConstant(-kInf);
  for (int i = 0; i < region.num_vertices; ++i) {
    const Eigen::Vector3d x = vertices.row(regions.vertices[region.first_vertex + i]).transpose();
    pu[i] = x.dot(region.tangent_u);
    pv[i] = x.dot(region.tangent_v);
    pw[i] = x.dot(region.axis);
    region.box_min = region.box_min.cwiseMin(x);
    region.box_max = region.box_max.cwiseMax(x);
  }
  auto extent = [&](const double* p, double& lo, double& hi) {
    lo = kInf;
    hi = -kInf;
    for (int i = 0; i < region.num_vertices; ++i) {
      lo = std::min(lo, p[i]);
      hi = std::max(hi, p[i]);
    }
  };
  extent(pu, region.u_min, region.u_max);
  extent(pv, region.v_min, region.v_max);
  extent(pw, region.w_min, region.w_max);
  region.spread_u = region.spread_v = 0.0;
  for (int j = region.first; j < region.first + region.count; ++j) {
    const Eigen::Vector3i& c = regions.local_corners[j];
    FrameBox& box = regions.triangle_box[j];
    box.u_lo = std::min({pu[c[0]], pu[c[1]], pu[c[2]]});
    box.u_hi = std::max({pu[c[0]], pu[c[1]], pu[c[2]]});
    box.v_lo = std::min({pv[c[0]], pv[c[1]], pv[c[2]]});
    box.v_hi = std::max({pv[c[0]], pv[c[1]], pv[c[2]]});
    box.w_lo = std::min({pw[c[0]], pw[c[1]], pw[c[2]]});
    box.w_hi = std::max({pw[c[0]], pw[c[1]], pw[c[2]]});
    const double cu = (pu[c[0]] + pu[c[1]] + pu[c[2]]) / 3.0;
    const double cv = (pv[c[0]] + pv[c[1]] + pv[c[2]]) / 3.0;
    regions.centroid_u[j] = cu;
    regions.centroid_v[j] = cv;
    region.spread_u = std::max({region.spread_u, cu - box.u_lo, box.u_hi - cu});
    region.spread_v = std::max({region.spread_v, cv - box.v_lo, box.v_hi - cv});
  }
}

/// Lists each region's vertices once and its triangles' corners as indices into them.
void IndexRegionVertices(const SurfacePseudonormals& mesh, int num_vertices,
                         MeshColliderRegions& regions) {
  std::vector<int> local(num_vertices, -1);
  regions.local_corners.resize(regions.triangles.size());
  int largest = 0;
  for (MeshColliderRegion& region : regions.data) {
    region.first_vertex = static_cast<int>(regions.vertices.size());
    for (int j = region.first; j < region.first + region.count; ++j) {
      const Eigen::Vector3i& tri = mesh.triangles()[regions.triangles[j]];
      for (int k = 0; k < 3; ++k) {
        if (local[tri[k]] < 0) {
          local[tri[k]] = static_cast<int>(regions.vertices.size()) - region.first_vertex;
          regions.vertices.push_back(tri[k]);
        }
        regions.local_corners[j][k] = local[tri[k]];
      }
    }
    region.num_vertices = static_cast<int>(regions.vertices.size()) - region.first_vertex;
    largest = std::max(largest, region.num_vertices);
    for (int i = region.first_vertex; i < region.first_vertex + region.num_vertices; ++i) {
      local[regions.vertices[i]] = -1;
    }
  }
  regions.project_u.assign(largest, 0.0);
  regions.project_v.assign(largest, 0.0);
  regions.project_w.assign(largest, 0.0);
}

/// Sorts a region's triangles into its grid cells by centroid (a counting sort).
void BinRegion(MeshColliderRegions& regions, MeshColliderRegion& region) {
  const int num_cells = region.cells_u * region.cells_v;
  region.cell_size_u = std::max((region.u_max - region.u_min) / region.cells_u, 1e-12);
  region.cell_size_v = std::max((region.v_max - region.v_min) / region.cells_v, 1e-12);
  int* start = &regions.cell_start[region.cell_first];
  std::fill(start, start + num_cells + 1, 0);
  for (int j = region.first; j < region.first + region.count; ++j) {
    const int cell =
        CellIndex(regions.centroid_v[j], region.v_min, region.cell_size_v, region.cells_v) *
            region.cells_u +
        CellIndex(regions.centroid_u[j], region.u_min, region.cell_size_u, region.cells_u);
    regions.triangle_cell[j] = cell;
    ++start[cell + 1];
  }
  FrameBox* box = &regions.cell_box[region.cell_first];
  std::fill(box, box + num_cells, FrameBox{});
  for (int j = region.first; j < region.first + region.count; ++j) {
    box[regions.triangle_cell[j]].Add(regions.triangle_box[j]);
  }
  for (int c = 0; c < num_cells; ++c) start[c + 1] += start[c];
  std::copy(start, start + num_cells, regions.cursor.begin());
  for (int j = region.first; j < region.first + region.count; ++j) {
    regions.cell_triangles[region.first + regions.cursor[regions.triangle_cell[j]]++] =
        regions.triangles[j];
  }
}

/// Copies a region's triangles, in grid order, into the packed records.
void PackRegion(const SurfacePseudonormals& mesh, const Points& vertices,
                MeshColliderRegions& regions, const MeshColliderRegion& region) {
  for (int j = region.first; j < region.first + region.count; ++j) {
    const Eigen::Vector3i& tri = mesh.triangles()[regions.cell_triangles[j]];
    PackedTriangle& packed = regions.packed[j];
    packed.a = vertices.row(tri[0]).transpose();
    packed.b = vertices.row(tri[1]).transpose();
    packed.c = vertices.row(tri[2]).transpose();
    packed.box_min = packed.a.cwiseMin(packed.b).cwiseMin(packed.c);
    packed.box_max = packed.a.cwiseMax(packed.b).cwiseMax(packed.c);
    packed.normal = mesh.double_area(regions.cell_triangles[j]) > 0.0
                        ? mesh.face_normal(regions.cell_triangles[j])
                        : Eigen::Vector3d::Zero();
  }
}

/// Distance [m] from `x` to the interval [lo, hi] (0 inside).
inline double IntervalGap(double x, double lo, double hi) {
  return std::max(std::max(lo - x, x - hi), 0.0);
}

/// Squared distance [m²] from `p` to the box [lo, hi] (0 inside).
inline double SquaredBoxDistance(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                 const Eigen::Vector3d& p) {
  const double x = IntervalGap(p.x(), lo.x(), hi.x());
  const double y = IntervalGap(p.y(), lo.y(), hi.y());
  const double z = IntervalGap(p.z(), lo.z(), hi.z());
  return x * x + y * y + z * z;
}

/// Fits a region to the collider's current vertices.
void FitRegion(MeshColliderRegions& r, MeshColliderRegion& region) {
  ProjectRegion(*r.mesh, *r.skin, r, region);
  BinRegion(r, region);
  PackRegion(*r.mesh, *r.skin, r, region);
  region.stale = false;
  region.travel = 0.0;
}

/// Fits a region a query has reached, if Update left it stale (lazy refit). Its tree box
/// stays the grown one until the next Update: larger than needed, never too small.
void Freshen(MeshColliderRegions& r, int region) {
  if (r.data[region].stale) FitRegion(r, r.data[region]);
}

}  // namespace

void MeshCollider::Refit(bool all) {
  // Vertex pseudonormals only for the few closest points at a vertex (Of with vertices_).
  normals_.Update(vertices_, /*vertex_normals=*/false);
  MeshColliderRegions& r = *regions_;
  for (MeshColliderRegion& region : r.data) {
    if (all || !std::isfinite(region.travel)) {
      FitRegion(r, region);
    } else {
      region.stale = region.travel > 0.0;
    }
    // Boxes fattened by the thickness; the query box adds the margin and the motion. A
    // stale region's box grows by how far its vertices may have moved since it was fitted.
    const double grow = settings_.thickness + region.travel;
    const btVector3 fatten(grow, grow, grow);
    btDbvtVolume box = btDbvtVolume::FromMM(ToBullet(region.box_min) - fatten,
                                            ToBullet(region.box_max) + fatten);
    r.trees[region.piece]->update(region.leaf, box);
  }
}

void MeshCollider::AddTravel(const Points& skinned_vertices) {
  for (Eigen::Index v = 0; v < vertices_.rows(); ++v) {
    vertex_step_[v] = (skinned_vertices.row(v) - vertices_.row(v)).squaredNorm();
  }
  std::fill(piece_step_.begin(), piece_step_.end(), 0.0);
  for (int t = 0; t < normals_.num_triangles(); ++t) {
    double& step = piece_step_[normals_.piece_of(t)];
    for (int k = 0; k < 3; ++k) {
      const double squared = vertex_step_[normals_.triangles()[t][k]];
      // NaN-proof: a non-finite step makes the travel infinite, so no bound is trusted.
      step = std::isfinite(squared) ? std::max(step, squared) : kInf;
    }
  }
  for (std::size_t p = 0; p < piece_step_.size(); ++p) piece_travel_[p] += std::sqrt(piece_step_[p]);
  MeshColliderRegions& r = *regions_;
  for (MeshColliderRegion& region : r.data) {
    double step = 0.0;
    for (int i = region.first_vertex; i < region.first_vertex + region.num_vertices; ++i) {
      const double squared = vertex_step_[r.vertices[i]];
      step = std::isfinite(squared) ? std::max(step, squared) : kInf;
    }
    region.travel += std::sqrt(step);
  }
}

void MeshCollider::Update(const std::vector<Eigen::Isometry3d>& /*joint_world*/,
                          const Points& skinned_vertices, double dt) {
  if (skinned_vertices.rows() != vertices_.rows()) return;
  AddTravel(skinned_vertices);
  if (has_pose_ && dt > 0.0) {
    vertex_velocities_.noalias() = (skinned_vertices - vertices_) / dt;
  } else {
    vertex_velocities_.setZero();
  }
  max_vertex_speed_ = vertex_velocities_.rowwise().norm().maxCoeff();
  if (!std::isfinite(max_vertex_speed_)) max_vertex_speed_ = 0.0;
  // Per piece, the fastest of its vertices [m/s] (+inf if not finite, so nothing is skipped
  // for its sake).
  for (Eigen::Index v = 0; v < vertices_.rows(); ++v) {
    vertex_step_[v] = vertex_velocities_.row(v).squaredNorm();
  }
  std::fill(piece_speed_.begin(), piece_speed_.end(), 0.0);
  for (int t = 0; t < normals_.num_triangles(); ++t) {
    double& speed = piece_speed_[normals_.piece_of(t)];
    for (int k = 0; k < 3; ++k) {
      const double squared = vertex_step_[normals_.triangles()[t][k]];
      speed = std::isfinite(squared) ? std::max(speed, squared) : kInf;
    }
  }
  for (double& speed : piece_speed_) speed = std::sqrt(speed);
  vertices_ = skinned_vertices;
  has_pose_ = true;
  Refit(/*all=*/!options_.lazy_refit);
}

namespace {

/// A particle's query box for search radius `radius` [m]: `point` ± (radius − thickness),
/// the region boxes being fattened by the thickness already.
btDbvtVolume QueryBox(const Eigen::Vector3d& point, double radius, double thickness) {
  const double half = std::max(radius - thickness, 0.0);
  const btVector3 center = ToBullet(point);
  const btVector3 extent(half, half, half);
  return btDbvtVolume::FromMM(center - extent, center + extent);
}

/// The body region a leaf of the region tree stands for.
int RegionOf(const btDbvtNode* leaf) {
  return static_cast<int>(reinterpret_cast<std::intptr_t>(leaf->data));
}

/// Visits, depth first, every leaf of `tree` whose box overlaps `query`, counting each node
/// examined in `num_tests`. The per-particle and the per-region searches both walk the
/// trees this way, piece by piece, so a particle meets its regions (and ties between
/// equally close triangles break) in the same order in both.
template <class Visit>
void VisitOverlappingLeaves(MeshColliderRegions& r, const btDbvt& tree,
                            const btDbvtVolume& query, long long& num_tests, Visit&& visit) {
  WalkTree(
      tree, r.stack,
      [&](const btDbvtNode* node) {
        ++num_tests;
        return Intersect(node->volume, query);
      },
      [](const btDbvtNode*) { return 1; },
      [&](const btDbvtNode* leaf) {
        visit(leaf);
        return true;
      });
}

/// The part of WalkRay in one region: only the grid cells whose triangles can meet the ray
/// where it runs through the region's slab (a ray leaving the skin crosses a region's slab
/// in a few cells, instead of meeting every triangle's box).
template <class Visit>
bool WalkRayInRegion(const MeshColliderRegions& r, const MeshColliderRegion& region,
                     const Eigen::Vector3d& point, const Eigen::Vector3d& direction,
                     const Eigen::Vector3d& inverse, Visit&& visit) {
  // The ray's parameters within the slab [w_min, w_max] along the region's axis.
  const double w = point.dot(region.axis), dw = direction.dot(region.axis);
  double t_lo = 0.0, t_hi = kInf;
  if (dw != 0.0) {
    const double t0 = (region.w_min - kRoundingSlack - w) / dw;
    const double t1 = (region.w_max + kRoundingSlack - w) / dw;
    t_lo = std::max(0.0, std::min(t0, t1));
    t_hi = std::max(t0, t1);
  } else if (w < region.w_min - kRoundingSlack || w > region.w_max + kRoundingSlack) {
    return true;
  }
  if (t_lo > t_hi) return true;
  // Where it runs in the plane meanwhile, clipped to the grid grown by the spreads.
  auto span = [&](const Eigen::Vector3d& tangent, double lo, double hi, double spread) {
    const double x = point.dot(tangent), dx = direction.dot(tangent);
    const double a = x + dx * t_lo;
    const double b = dx == 0.0 ? a : x + dx * std::min(t_hi, 1e3);  // 1 km: beyond any body
    return std::pair(std::max(std::min(a, b) - spread, lo),
                     std::min(std::max(a, b) + spread, hi));
  };
  const auto [u_lo, u_hi] = span(region.tangent_u, region.u_min, region.u_max,
                                 region.spread_u + kRoundingSlack);
  const auto [v_lo, v_hi] = span(region.tangent_v, region.v_min, region.v_max,
                                 region.spread_v + kRoundingSlack);
  if (u_lo > u_hi || v_lo > v_hi) return true;
  const int cu_lo = CellIndex(u_lo, region.u_min, region.cell_size_u, region.cells_u);
  const int cu_hi = CellIndex(u_hi, region.u_min, region.cell_size_u, region.cells_u);
  const int cv_lo = CellIndex(v_lo, region.v_min, region.cell_size_v, region.cells_v);
  const int cv_hi = CellIndex(v_hi, region.v_min, region.cell_size_v, region.cells_v);
  const int* start = &r.cell_start[region.cell_first];
  for (int cv = cv_lo; cv <= cv_hi; ++cv) {
    for (int cu = cu_lo; cu <= cu_hi; ++cu) {
      const int cell = cv * region.cells_u + cu;
      for (int j = region.first + start[cell]; j < region.first + start[cell + 1]; ++j) {
        const PackedTriangle& t = r.packed[j];
        if (!RayMeetsBox(t.box_min, t.box_max, point, inverse)) continue;
        const Crossing crossing = RayCrossing(point, direction, t.a, t.b, t.c);
        if (crossing == Crossing::kNone) continue;
        if (crossing == Crossing::kUncertain || !visit(j, crossing)) return false;
      }
    }
  }
  return true;
}

/// Walks the ray from `point` along `direction` through the region tree of `piece`:
/// `visit(slot, crossing)` for each packed triangle it crosses (kExit or kEntry), ending
/// the walk when it returns false. Returns false when it ended so, or when the ray passes
/// too near an edge or a plane to count.
template <class Visit>
bool WalkRay(MeshColliderRegions& r, int piece, const Eigen::Vector3d& point,
             const Eigen::Vector3d& direction, Visit&& visit) {
  const Eigen::Vector3d inverse = direction.cwiseInverse();
  return WalkTree(
      *r.trees[piece], r.stack,
      [&](const btDbvtNode* node) {
        return RayMeetsBox(ToEigen(node->volume.Mins()), ToEigen(node->volume.Maxs()), point,
                           inverse);
      },
      [](const btDbvtNode*) { return 1; },  // a count: any order
      [&](const btDbvtNode* leaf) {
        Freshen(r, RegionOf(leaf));
        return WalkRayInRegion(r, r.data[RegionOf(leaf)], point, direction, inverse, visit);
      });
}

}  // namespace

MeshCollider::Nearest MeshCollider::Query(const Eigen::Vector3d& point, double reach,
                                          double threshold, double h, int particle,
                                          const Source& source) {
  MeshColliderRegions& r = *regions_;
  const int num_pieces = normals_.num_pieces();
  // Pieces are searched a little beyond the reach: what is found there takes no part in
  // the answer, but its distance and sign are remembered, so the piece stays out of the
  // next searches until it could matter.
  const double extended = reach + kBoundExtension;
  // What the particle's last query learnt about each piece, moved to now: since then the
  // particle has moved `slack` and the piece `piece_travel_` more, and its signed and
  // unsigned distances change by at most that much (both are 1-Lipschitz in the point,
  // and no surface point moves farther than its vertices).
  PieceMemory* memory = particle >= 0 ? &memory_[num_pieces * particle] : nullptr;
  const double slack =
      memory != nullptr ? (point - anchors_.row(particle).transpose()).norm() : 0.0;
  int num_order = 0;
  for (int piece = 0; piece < num_pieces; ++piece) {
    double signed_bound = -kInf;
    if (memory != nullptr && options_.reuse_bounds) {
      const double moved = piece_travel_[piece] + slack;
      // Out of reach (as a full search would find it): not searched.
      if (memory[piece].distance_bound - moved > reach) {
        r.piece_state[piece] = kOutOfReach;
        continue;
      }
      signed_bound = memory[piece].signed_bound - moved;
    }
    r.piece_state[piece] = kSkipped;
    r.order[num_order++] = {piece, signed_bound};
  }
  // Pieces of unknown sign first (their bound is −inf), then lowest bound first.
  InsertionSort(r.order.data(), num_order,
                [](const PieceBound& a, const PieceBound& b) { return a.bound < b.bound; });
  r.lowest = kInf;
  auto search = [&](int piece) {
    r.piece_state[piece] = kSearched;
    ActivatePiece(piece, extended * extended);
    // A piece whose whole box lies beyond the extended reach needs no walk, and its box's
    // distance bounds it better than the reach.
    const btDbvtNode* root = r.trees[piece]->m_root;
    ++num_tests_;
    const double root_squared =
        root == nullptr ? kInf
                        : SquaredBoxDistance(ToEigen(root->volume.Mins()),
                                             ToEigen(root->volume.Maxs()), point);
    r.unfound_bound[piece] = std::max(extended, std::sqrt(root_squared));
    if (root_squared > extended * extended) {
      ResolvePiece(piece, point, reach);
      return;
    }
    const int hint = memory != nullptr ? memory[piece].triangle : -1;
    if (hint >= 0) TryTriangle(hint, point);  // its last nearest triangle starts the radius
    const int count = Collect(point, piece, std::sqrt(r.best_squared[piece]), source);
    SearchCandidates(point, count);
    ResolvePiece(piece, point, reach);
  };
  // A piece is skipped when its bound exceeds the lowest signed distance found so far (it
  // cannot be the nearest) or its own threshold (as the nearest it would not matter).
  auto over_threshold = [&](int piece, double bound) {
    return bound > threshold + h * piece_speed_[piece];
  };
  for (int k = 0; k < num_order; ++k) {
    const PieceBound& entry = r.order[k];
    if (!(entry.bound > r.lowest) && !over_threshold(entry.piece, entry.bound)) {
      search(entry.piece);
    }
  }
  // The nearest so far matters (it is within its threshold): a piece skipped by its own
  // threshold alone may still be nearer, and is searched.
  const int winner = Winner();
  if (winner >= 0 && !over_threshold(winner, r.lowest)) {
    for (int k = 0; k < num_order; ++k) {
      const PieceBound& entry = r.order[k];
      if (r.piece_state[entry.piece] == kSkipped && !(entry.bound > r.lowest)) {
        search(entry.piece);
      }
    }
  }
  if (memory != nullptr) Remember(memory, particle, point, slack);
  return Finish(point);
}

void MeshCollider::Remember(PieceMemory* memory, int particle, const Eigen::Vector3d& point,
                            double slack) {
  MeshColliderRegions& r = *regions_;
  for (int piece = 0; piece < normals_.num_pieces(); ++piece) {
    PieceMemory& m = memory[piece];
    if (r.piece_state[piece] != kSearched) {
      // Not searched: the bounds carry over to the new anchor.
      m.signed_bound -= slack;
      m.distance_bound -= slack;
      continue;
    }
    const double travel = piece_travel_[piece];
    if (r.best_triangle[piece] >= 0) {
      const double distance = r.piece_distance[piece];
      m.triangle = r.best_triangle[piece];
      m.signed_bound = (piece_closed_[piece] ? distance : -kInf) + travel;
      m.distance_bound = std::abs(distance) + travel;
    } else {
      // Nothing within the extended reach (or the piece's box); the sign is unknown
      // (inside or out). The old bound, carried over, may still be the better one.
      m.signed_bound = -kInf;
      m.distance_bound = std::max(r.unfound_bound[piece] + travel, m.distance_bound - slack);
    }
  }
  anchors_.row(particle) = point.transpose();
}

int MeshCollider::Collect(const Eigen::Vector3d& point, int piece, double radius,
                          const Source& source) {
  MeshColliderRegions& r = *regions_;
  const double radius_squared = radius * radius;
  const btDbvtVolume box = QueryBox(point, radius, settings_.thickness);
  int count = 0;
  auto add = [&](int region) {
    Freshen(r, region);
    // The query box is a cube around the ball; its corners reach further.
    const double squared =
        SquaredBoxDistance(r.data[region].box_min, r.data[region].box_max, point);
    if (squared <= radius_squared) r.near[count++] = RegionCandidate{region, squared};
  };
  if (source.from_list) {
    for (int c = source.first; c < source.first + source.count; ++c) {
      const btDbvtNode* node = r.candidates[c];
      const int region = RegionOf(node);
      if (r.data[region].piece != piece) continue;
      ++num_tests_;
      if (Intersect(node->volume, box)) add(region);
    }
    return count;
  }
  VisitOverlappingLeaves(r, *r.trees[piece], box, num_tests_,
                         [&](const btDbvtNode* leaf) { add(RegionOf(leaf)); });
  return count;
}

int MeshCollider::GatherCandidates(const Eigen::Vector3d& box_min,
                                   const Eigen::Vector3d& box_max) {
  MeshColliderRegions& r = *regions_;
  int count = 0;
  const btDbvtVolume box = btDbvtVolume::FromMM(ToBullet(box_min), ToBullet(box_max));
  for (const auto& tree : r.trees) {
    VisitOverlappingLeaves(r, *tree, box, num_tests_,
                           [&](const btDbvtNode* leaf) { r.candidates[count++] = leaf; });
  }
  return count;
}

void MeshCollider::ActivatePiece(int piece, double radius_squared) {
  MeshColliderRegions& r = *regions_;
  r.best_squared[piece] = radius_squared;
  r.touched.push_back(piece);
}

void MeshCollider::TryTriangle(int triangle, const Eigen::Vector3d& point) {
  MeshColliderRegions& r = *regions_;
  const int piece = normals_.piece_of(triangle);
  ++num_tests_;
  const Eigen::Vector3i& tri = normals_.triangles()[triangle];
  const TrianglePoint closest =
      ClosestPointOnTriangle(point, vertices_.row(tri[0]).transpose(),
                             vertices_.row(tri[1]).transpose(), vertices_.row(tri[2]).transpose());
  const double squared = (point - closest.point).squaredNorm();
  if (squared > r.best_squared[piece]) return;
  r.best_squared[piece] = squared;
  r.best_triangle[piece] = triangle;
  r.best_point[piece] = closest;
}

void MeshCollider::SearchCandidates(const Eigen::Vector3d& point, int count) {
  MeshColliderRegions& r = *regions_;
  // Nearest box first (an insertion sort, stable: equal boxes keep the walk's order): the
  // nearest triangle is usually in the first region, and the radius it sets rules out
  // the others by their boxes alone.
  RegionCandidate* near = r.near.data();
  InsertionSort(near, count, [](const RegionCandidate& a, const RegionCandidate& b) {
    return a.squared_distance < b.squared_distance;
  });
  for (int i = 0; i < count; ++i) {
    const MeshColliderRegion& region = r.data[near[i].region];
    ++num_tests_;  // the region's box against the piece's current radius
    if (near[i].squared_distance > r.best_squared[region.piece]) continue;
    SearchRegion(region, point);
  }
}

void MeshCollider::SearchRegion(const MeshColliderRegion& region, const Eigen::Vector3d& point) {
  MeshColliderRegions& r = *regions_;
  const double& best = r.best_squared[region.piece];
  ++num_tests_;  // the region's box in its own frame: the slab along its mean normal
  const double u = point.dot(region.tangent_u);
  const double v = point.dot(region.tangent_v);
  const double w = point.dot(region.axis);
  const double gap_w = IntervalGap(w, region.w_min, region.w_max);
  const double gap_u = IntervalGap(u, region.u_min, region.u_max);
  const double gap_v = IntervalGap(v, region.v_min, region.v_max);
  if (gap_u * gap_u + gap_v * gap_v + gap_w * gap_w > best) return;
  const FrameBox* box = &r.cell_box[region.cell_first];
  // The box of a cell's triangles bounds their distance from below. The cell under the
  // point first: on a surface it usually holds the nearest triangle, whose distance then
  // rules out most other cells.
  auto search_if_near = [&](int cell) {
    ++num_tests_;  // a grid cell
    const FrameBox& b = box[cell];
    const double du = IntervalGap(u, b.u_lo, b.u_hi);
    const double dv = IntervalGap(v, b.v_lo, b.v_hi);
    const double dw = IntervalGap(w, b.w_lo, b.w_hi);
    if (du * du + dv * dv + dw * dw <= best) SearchCell(region, cell, point);
  };
  const int home_u = CellIndex(u, region.u_min, region.cell_size_u, region.cells_u);
  const int home_v = CellIndex(v, region.v_min, region.cell_size_v, region.cells_v);
  search_if_near(home_v * region.cells_u + home_u);
  // The other cells that can hold a triangle within the radius: a triangle binned in a
  // cell (by centroid) lies within its spread of the cell's rectangle. Row by row, a disc
  // of cells, not a square.
  const double spread_u = region.spread_u + kRoundingSlack;
  const double spread_v = region.spread_v + kRoundingSlack;
  const double gap_w_squared = gap_w * gap_w;
  const double radius = std::sqrt(best);
  const int v_lo = CellIndex(v - radius - spread_v, region.v_min, region.cell_size_v,
                             region.cells_v);
  const int v_hi = CellIndex(v + radius + spread_v, region.v_min, region.cell_size_v,
                             region.cells_v);
  for (int cv = v_lo; cv <= v_hi; ++cv) {
    ++num_tests_;  // a row of cells
    const double row_gap = IntervalGap(v, region.v_min + cv * region.cell_size_v - spread_v,
                                       region.v_min + (cv + 1) * region.cell_size_v + spread_v);
    const double row_squared = gap_w_squared + row_gap * row_gap;
    if (row_squared > best) continue;
    const double half_width = std::sqrt(best - row_squared) + spread_u;
    const int u_lo = CellIndex(u - half_width, region.u_min, region.cell_size_u, region.cells_u);
    const int u_hi = CellIndex(u + half_width, region.u_min, region.cell_size_u, region.cells_u);
    for (int cu = u_lo; cu <= u_hi; ++cu) {
      if (cu != home_u || cv != home_v) search_if_near(cv * region.cells_u + cu);
    }
  }
}

void MeshCollider::SearchCell(const MeshColliderRegion& region, int cell,
                              const Eigen::Vector3d& point) {
  MeshColliderRegions& r = *regions_;
  const int piece = region.piece;
  double best = r.best_squared[piece];
  const int* start = &r.cell_start[region.cell_first];
  const int end = region.first + start[cell + 1];
  for (int j = region.first + start[cell]; j < end; ++j) {
    // A triangle: its box and its plane first (lower bounds), its closest point only if
    // both are near enough.
    ++num_tests_;
    const PackedTriangle& t = r.packed[j];
    if (SquaredBoxDistance(t.box_min, t.box_max, point) > best) continue;
    const double plane = t.normal.dot(point - t.a);
    if (plane * plane > best) continue;
    const TrianglePoint closest = ClosestPointOnTriangle(point, t.a, t.b, t.c);
    const double squared = (point - closest.point).squaredNorm();
    // Ties keep the first found, except that the first triangle may sit exactly at the
    // radius.
    if (squared > best || (squared == best && r.best_triangle[piece] >= 0)) continue;
    best = squared;
    r.best_triangle[piece] = r.cell_triangles[j];
    r.best_point[piece] = closest;
  }
  r.best_squared[piece] = best;
}

void MeshCollider::ResolvePiece(int piece, const Eigen::Vector3d& point, double reach) {
  MeshColliderRegions& r = *regions_;
  const int t = r.best_triangle[piece];
  if (t < 0) {
    r.piece_distance[piece] = kInf;
    return;
  }
  // Each piece's own closest feature decides its sign; the union takes the smallest, among
  // the pieces within reach.
  const TrianglePoint& closest = r.best_point[piece];
  const double distance = std::sqrt(r.best_squared[piece]);
  const bool inside = (point - closest.point).dot(normals_.Of(t, closest.feature, vertices_)) < 0.0;
  r.piece_distance[piece] = inside ? -distance : distance;
  r.in_reach[piece] = r.best_squared[piece] <= reach * reach;
  if (r.in_reach[piece]) r.lowest = std::min(r.lowest, r.piece_distance[piece]);
}

int MeshCollider::Winner() const {
  const MeshColliderRegions& r = *regions_;
  double lowest = kInf;
  int winner = -1;
  for (int piece : r.touched) {
    if (r.best_triangle[piece] >= 0 && r.in_reach[piece] && r.piece_distance[piece] < lowest) {
      lowest = r.piece_distance[piece];
      winner = piece;
    }
  }
  return winner;
}

MeshCollider::Nearest MeshCollider::Finish(const Eigen::Vector3d& point) {
  MeshColliderRegions& r = *regions_;
  Nearest nearest;
  const int winner = Winner();
  if (winner >= 0) {
    nearest.signed_distance = r.piece_distance[winner];
    const int t = r.best_triangle[winner];
    const TrianglePoint& closest = r.best_point[winner];
    const Eigen::Vector3d offset = point - closest.point;
    const double distance = std::abs(nearest.signed_distance);
    const bool inside = nearest.signed_distance < 0.0;
    nearest.found = true;
    nearest.piece = winner;
    nearest.normal = distance > 0.0 ? Eigen::Vector3d((inside ? -offset : offset) / distance)
                                    : normals_.Of(t, closest.feature, vertices_);
    nearest.surface_velocity = SurfaceVelocity(t, closest.barycentric);
    nearest.closest = closest.point;
  }
  for (int piece : r.touched) r.best_triangle[piece] = -1;  // ready for the next query
  r.touched.clear();
  return nearest;
}

double MeshCollider::ReachOf(const Eigen::Vector3d& velocity, double h, double margin) const {
  // Far enough for a contact at the start (inside the shell, however deep within
  // max_penetration) and for one reached during the step at the relative speed.
  return settings_.thickness +
         std::max(margin + h * (velocity.norm() + max_vertex_speed_), options_.max_penetration);
}

double MeshCollider::ContactThreshold(const Eigen::Vector3d& velocity, double h,
                                      double margin) const {
  // Plus h × the piece's fastest vertex: above it, d + h·(v − v_surface)·n >=
  // d − h·(|v| + |v_surface|) > thickness + margin.
  return settings_.thickness + margin + h * velocity.norm();
}

bool MeshCollider::MakeContact(int particle, const Eigen::Vector3d& velocity,
                               const Nearest& nearest, double h, double margin,
                               Contact& contact) const {
  const double shell = settings_.thickness;
  const double distance = nearest.signed_distance;
  const double relative_normal_velocity =
      (velocity - nearest.surface_velocity).dot(nearest.normal);
  if (distance >= shell && distance + h * relative_normal_velocity > shell + margin) {
    return false;
  }
  contact = Contact{};
  contact.particle = particle;
  contact.normal = nearest.normal;
  contact.target_normal_velocity = ContactNormalVelocity(
      nearest.surface_velocity.dot(nearest.normal), distance - shell, relative_normal_velocity, h);
  contact.friction = settings_.friction;
  contact.shell_offset = nearest.normal.dot(nearest.closest) + shell;  // the body stands at the step's end
  return true;
}

void MeshCollider::FindContacts(const Points& positions, const Points& velocities, double h,
                                double margin, std::vector<Contact>& contacts) {
  stats_ = BodyCollisionStats{};
  num_tests_ = 0;
  num_queries_ = 0;
  if (!(h > 0.0) || positions.rows() != velocities.rows()) return;
  margin = std::isfinite(margin) ? std::max(margin, 0.0) : 0.0;
  SizeMemory(positions.rows());
  if (options_.cloth_regions && cloth_ != nullptr &&
      positions.rows() == cloth_->num_particles()) {
    FindContactsPerRegion(positions, velocities, h, margin, contacts);
  } else {
    FindContactsPerParticle(positions, velocities, h, margin, contacts);
  }
  stats_.num_tests = num_tests_;
}

void MeshCollider::FindContactsPerParticle(const Points& positions, const Points& velocities,
                                           double h, double margin,
                                           std::vector<Contact>& contacts) {
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    const Eigen::Vector3d v = velocities.row(i).transpose();
    const double reach = ReachOf(v, h, margin);
    near_piece_[i] = -1;
    if (!(reach < kInf) || !x.allFinite()) continue;
    ++num_queries_;
    const Nearest nearest =
        Query(x, reach, ContactThreshold(v, h, margin), h, MemoryOf(static_cast<int>(i)),
              Source{});
    near_piece_[i] = NearPiece(nearest);
    Contact contact;
    if (!nearest.found || !MakeContact(static_cast<int>(i), v, nearest, h, margin, contact)) {
      continue;
    }
    contacts.push_back(contact);
    ++stats_.num_contacts;
  }
}

void MeshCollider::FindContactsPerRegion(const Points& positions, const Points& velocities,
                                         double h, double margin,
                                         std::vector<Contact>& contacts) {
  const double shell = settings_.thickness;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const double reach = ReachOf(velocities.row(i).transpose(), h, margin);
    const bool valid = reach < kInf && positions.row(i).allFinite();
    near_piece_[i] = -1;
    // The largest query box Query walks, so a region's box holds its particles' boxes.
    half_extents_[i] = valid ? std::max(reach + kBoundExtension - shell, 0.0) : -1.0;
    reaches_[i] = reach;
  }
  num_tests_ += cloth_->Refit(positions, half_extents_.data(), options_.cloth_adaptive,
                              options_.cloth_cone_period);
  // Fixed regions: no angle passes, so the walk goes down to the base regions.
  const double flatness = options_.cloth_adaptive ? options_.cloth_flatness_angle : -1.0;
  for (int k : cloth_->Select(flatness)) {
    const ClothRegionNode& node = cloth_->nodes()[k];
    if (!(node.box_min.x() <= node.box_max.x())) continue;  // no valid particle
    ++num_queries_;
    const int count = GatherCandidates(node.box_min, node.box_max);
    if (count > 0) TestClothNode(k, 0, count, positions, velocities, h, margin);
  }
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    if (!has_contact_[i]) continue;
    has_contact_[i] = 0;
    contacts.push_back(particle_contacts_[i]);
    ++stats_.num_contacts;
  }
}

void MeshCollider::TestClothNode(int k, int first, int count, const Points& positions,
                                 const Points& velocities, double h, double margin) {
  MeshColliderRegions& r = *regions_;
  const ClothRegionNode& node = cloth_->nodes()[k];
  if (node.num_children > 0) {
    // Each child keeps the candidates its own box overlaps, in the same order, written
    // after the parent's list.
    const int child_first = first + count;
    for (int c = node.first_child; c < node.first_child + node.num_children; ++c) {
      const ClothRegionNode& child = cloth_->nodes()[c];
      if (!(child.box_min.x() <= child.box_max.x())) continue;
      const btDbvtVolume box =
          btDbvtVolume::FromMM(ToBullet(child.box_min), ToBullet(child.box_max));
      int child_count = 0;
      for (int j = first; j < first + count; ++j) {
        ++num_tests_;
        if (Intersect(r.candidates[j]->volume, box)) {
          r.candidates[child_first + child_count++] = r.candidates[j];
        }
      }
      if (child_count > 0) {
        TestClothNode(c, child_first, child_count, positions, velocities, h, margin);
      }
    }
    return;
  }
  const std::vector<int>& particles = cloth_->particles();
  for (int s = node.first; s < node.first + node.count; ++s) {
    const int p = particles[s];
    if (half_extents_[p] < 0.0) continue;
    const Eigen::Vector3d velocity = velocities.row(p).transpose();
    const Nearest nearest =
        Query(positions.row(p).transpose(), reaches_[p], ContactThreshold(velocity, h, margin),
              h, MemoryOf(p), Source{true, first, count});
    near_piece_[p] = NearPiece(nearest);
    if (!nearest.found) continue;
    has_contact_[p] = MakeContact(p, velocity, nearest, h, margin, particle_contacts_[p]);
  }
}

double MeshCollider::ProjectOut(Points& positions, Points& velocities) {
  if (positions.rows() != velocities.rows()) return 0.0;
  const Correction how = CorrectionFor(positions, settings_.thickness);
  double deepest = 0.0;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    deepest = std::max(deepest, ProjectParticleOut(i, how, positions, velocities));
  }
  return deepest;
}

double MeshCollider::ProjectOut(Points& positions, Points& velocities,
                                std::span<const int> particles) {
  return ProjectListedOut(positions, velocities, particles, settings_.thickness);
}

double MeshCollider::ProjectOutOfSkin(Points& positions, Points& velocities,
                                      std::span<const int> particles) {
  return ProjectListedOut(positions, velocities, particles, 0.0);
}

double MeshCollider::ProjectListedOut(Points& positions, Points& velocities,
                                      std::span<const int> particles, double shell) {
  if (positions.rows() != velocities.rows()) return 0.0;
  const Correction how = CorrectionFor(positions, shell);
  double deepest = 0.0;
  for (const int i : particles) {
    deepest = std::max(deepest, ProjectParticleOut(i, how, positions, velocities));
  }
  return deepest;
}

MeshCollider::Correction MeshCollider::CorrectionFor(const Points& positions,
                                                    double shell) const {
  Correction how;
  how.shell = shell;
  how.reach = settings_.thickness + options_.max_penetration;
  // The memory FindContacts left, when it was given these particles.
  how.remembered =
      UsesMemory() &&
      memory_.size() == static_cast<std::size_t>(normals_.num_pieces() * positions.rows());
  how.near_known = near_piece_.size() == static_cast<std::size_t>(positions.rows());
  return how;
}

double MeshCollider::ProjectParticleOut(Eigen::Index i, const Correction& how,
                                        Points& positions, Points& velocities) {
  const double shell = how.shell, reach = how.reach;
  double deepest = 0.0;
  // In a crease between two pieces (the back of a bent knee) moving out of one can move a
  // particle into the other: a few alternating passes, as the superquadric collider does.
  Eigen::Vector3d pushed = Eigen::Vector3d::Zero();  // the last pass's push direction
  for (int pass = 0; pass < kMeshProjectionPasses; ++pass) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    if (!x.allFinite()) break;
    const Nearest nearest =
        Query(x, reach, shell, 0.0, how.remembered ? static_cast<int>(i) : -1, Source{});
    // The piece whose skin was within reach at the step's start has none within reach
    // now: the particle left it by more than max_penetration in one step, or the skin
    // swept over it (a kicking leg through loose trousers) and it is deeper than that.
    if (pass == 0 && options_.find_buried && how.near_known && near_piece_[i] >= 0 &&
        SearchedBeyondReach(near_piece_[i])) {
      const double depth = ProjectOutLost(i, positions, velocities);
      if (depth > 0.0) {
        deepest = std::max(deepest, depth);
        continue;  // out of that piece: into another?
      }
    }
    if (!nearest.found) break;
    if (nearest.signed_distance >= shell) {
      // Outside by its nearest triangle, which buried skin can belie.
      if (options_.find_buried && nearest.signed_distance < reach) {
        deepest = std::max(deepest, ProjectOutBuried(i, nearest.normal, nearest.piece,
                                                     positions, velocities));
      }
      break;
    }
    if (pass == 0) deepest = std::max(deepest, shell - nearest.signed_distance);
    const double facing = pass > 0 ? pushed.dot(nearest.normal) : 0.0;
    if (facing < kPinchFacing) {
      // A pinch: the skin the last pass pushed the particle out of faces this one across
      // a gap narrower than two shells (an arm against the torso). Pushing out of this one
      // would push it as deep into that one; midway its signed distances to both are equal.
      const double back = PinchMidwayBack(shell - nearest.signed_distance, facing);
      positions.row(i) -= back * pushed.transpose();
      RemoveInwardVelocity(i, nearest.normal, nearest.surface_velocity, velocities);
      break;
    }
    positions.row(i) += (shell - nearest.signed_distance) * nearest.normal.transpose();
    RemoveInwardVelocity(i, nearest.normal, nearest.surface_velocity, velocities);
    pushed = nearest.normal;
  }
  return deepest;
}

Eigen::Vector3d MeshCollider::SurfaceVelocity(int triangle,
                                             const Eigen::Vector3d& weights) const {
  const Eigen::Vector3i& tri = normals_.triangles()[triangle];
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) velocity += weights[k] * vertex_velocities_.row(tri[k]).transpose();
  return velocity;
}

bool MeshCollider::SearchedBeyondReach(int piece) const {
  const MeshColliderRegions& r = *regions_;
  // A piece skipped by its bound is not that deep (its signed distance is above the
  // threshold); one out of reach was not within reach at the step's start either.
  return r.piece_state[piece] == kSearched &&
         (!(r.piece_distance[piece] < kInf) || !r.in_reach[piece]);
}

double MeshCollider::ProjectOutLost(Eigen::Index i, Points& positions, Points& velocities) {
  ++stats_.num_winding_checks;
  // Any ray counts the winding number; back against its velocity, the way a particle the
  // skin swept over came in, it likely leaves the body's boxes soonest.
  const Eigen::Vector3d velocity = velocities.row(i).transpose();
  const double speed = velocity.norm();
  const Eigen::Vector3d back = speed > 0.0 ? Eigen::Vector3d(-velocity / speed)
                                           : Eigen::Vector3d(0.36, 0.48, 0.8);
  // Only the piece that was near: deep in any other, the particle was lost before the step.
  return ProjectOutOfPiece(i, near_piece_[i], back, kLostParticleSearch, positions, velocities);
}

double MeshCollider::ProjectOutBuried(Eigen::Index i, const Eigen::Vector3d& outward,
                                      int folded, Points& positions, Points& velocities) {
  ++stats_.num_winding_checks;
  for (int piece = 0; piece < normals_.num_pieces(); ++piece) {
    // Inside the piece whose own nearest skin puts the particle outside, that piece is
    // folded through itself (a raised thigh skinned into the belly) and its exit may lie
    // far beyond max_penetration. In another piece the particle may have been lost long
    // before: a search that far would move it or not as the memory happened to search.
    const double max_depth = piece == folded ? kLostParticleSearch : options_.max_penetration;
    const double depth =
        ProjectOutOfPiece(i, piece, outward, max_depth, positions, velocities);
    if (depth > 0.0) return depth;
  }
  return 0.0;
}

double MeshCollider::ProjectOutOfPiece(Eigen::Index i, int piece,
                                       const Eigen::Vector3d& outward, double max_depth,
                                       Points& positions, Points& velocities) {
  const Eigen::Vector3d x = positions.row(i).transpose();
  // An open piece has no inside to count.
  if (!piece_closed_[piece] || !InsidePiece(piece, x, outward)) return 0.0;
  // Out where the winding number first falls to 0 along the nearest of a few rays, onto
  // the shell beyond (if that is outside: the skin there may be folded). The nearest
  // skin the particle lies behind need not lead out: folded skin nearer may bound more
  // skin. None within max_depth: lost.
  std::array<std::pair<RayExit, Eigen::Vector3d>, kNumExitRays> exits;
  int count = 0;
  for (const Eigen::Vector3d& direction : ExitRayDirections()) {
    RayExit exit;
    if (ExitAlong(piece, x, direction, exit) && exit.distance <= max_depth) {
      exits[count++] = {exit, direction};
    }
  }
  std::sort(exits.begin(), exits.begin() + count, [](const auto& a, const auto& b) {
    return a.first.distance < b.first.distance;
  });
  for (int k = 0; k < count; ++k) {
    const auto& [exit, direction] = exits[k];
    const Eigen::Vector3d target = x + (exit.distance + settings_.thickness) * direction;
    if (InsidePiece(piece, target, direction)) continue;
    ++stats_.num_buried;
    positions.row(i) = target.transpose();
    const PackedTriangle& t = regions_->packed[exit.slot];
    const Eigen::Vector3d weights =
        ClosestPointOnTriangle(x + exit.distance * direction, t.a, t.b, t.c).barycentric;
    RemoveInwardVelocity(i, t.normal,
                         SurfaceVelocity(regions_->cell_triangles[exit.slot], weights),
                         velocities);
    return exit.distance + settings_.thickness;
  }
  return 0.0;
}

bool MeshCollider::InsidePiece(int piece, const Eigen::Vector3d& point,
                               const Eigen::Vector3d& direction) {
  const btDbvtNode* root = regions_->trees[piece]->m_root;
  if (root == nullptr || SquaredBoxDistance(ToEigen(root->volume.Mins()),
                                            ToEigen(root->volume.Maxs()), point) > 0.0) {
    return false;  // outside the piece's box: winding 0
  }
  // Away from the skin first: such a ray leaves the body's boxes soonest.
  int winding = 0;
  if (direction.cwiseAbs().minCoeff() > 1e-9 && WindingInPiece(piece, point, direction, winding)) {
    return winding >= 1;
  }
  for (const Eigen::Vector3d& fallback : WindingRayDirections()) {
    if (WindingInPiece(piece, point, fallback, winding)) return winding >= 1;
  }
  return false;  // every ray grazes: the point is on the surface, not inside by any depth
}

bool MeshCollider::WindingInPiece(int piece, const Eigen::Vector3d& point,
                                  const Eigen::Vector3d& direction, int& winding) {
  winding = 0;
  return WalkRay(*regions_, piece, point, direction, [&](int, Crossing crossing) {
    winding += crossing == Crossing::kExit ? 1 : -1;
    return true;
  });
}

bool MeshCollider::ExitAlong(int piece, const Eigen::Vector3d& point,
                             const Eigen::Vector3d& direction, RayExit& exit) {
  const MeshColliderRegions& r = *regions_;
  std::array<RayExit, kMaxExitCrossings> crossings;
  int count = 0;
  const bool counted = WalkRay(*regions_, piece, point, direction, [&](int j, Crossing crossing) {
    if (count == kMaxExitCrossings) return false;
    const PackedTriangle& t = r.packed[j];
    const double along = t.normal.dot(direction);
    if (along == 0.0) return false;
    crossings[count++] = {t.normal.dot(t.a - point) / along, j,
                          crossing == Crossing::kExit ? 1 : -1};
    return true;
  });
  if (!counted) return false;
  std::sort(crossings.begin(), crossings.begin() + count,
            [](const RayExit& x, const RayExit& y) { return x.distance < y.distance; });
  // The winding at the point is the sum of all; going out, each exit takes one off.
  int winding = 0;
  for (int k = 0; k < count; ++k) winding += crossings[k].sign;
  for (int k = 0; k < count; ++k) {
    winding -= crossings[k].sign;
    if (winding == 0) {
      exit = crossings[k];
      return true;
    }
  }
  return false;
}

}  // namespace costume::sim
