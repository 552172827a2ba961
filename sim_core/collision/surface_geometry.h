#pragma once
/// @file
/// Geometry shared by the mesh distance and the mesh collider (paper §4, accurate method):
/// the closest point of a triangle with the feature it lies on, and the angle-weighted
/// pseudonormals of a triangle mesh (Bærentzen & Aanæs 2005, "Signed distance computation
/// using the angle weighted pseudonormal"), whose sign test is right at edges and vertices.

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// The feature of a triangle (a, b, c) a closest point lies on.
enum class TriangleFeature : std::uint8_t {
  kVertexA,
  kVertexB,
  kVertexC,
  kEdgeAB,
  kEdgeBC,
  kEdgeCA,
  kFace,
};

/// A closest point on a triangle.
struct TrianglePoint {
  /// The point [m].
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  /// Its barycentric weights of (a, b, c) [-], each in [0, 1], summing to 1.
  Eigen::Vector3d barycentric = Eigen::Vector3d(1.0, 0.0, 0.0);
  TriangleFeature feature = TriangleFeature::kVertexA;
};

/// The point of triangle (a, b, c) [m] closest to `p` [m], by Voronoi regions (Ericson,
/// Real-Time Collision Detection §5.1.5). A degenerate triangle gives a point of it, not
/// necessarily the closest. Never throws; never allocates.
TrianglePoint ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                     const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Whether the ray from `origin` with componentwise inverse direction `inverse` meets the
/// box [lo, hi] at a non-negative parameter (slab test). Never throws.
inline bool RayMeetsBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                        const Eigen::Vector3d& origin, const Eigen::Vector3d& inverse) {
  double near = 0.0, far = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    double t0 = (lo[k] - origin[k]) * inverse[k];
    double t1 = (hi[k] - origin[k]) * inverse[k];
    if (t0 > t1) std::swap(t0, t1);
    near = std::max(near, t0);
    far = std::min(far, t1);
    if (near > far) return false;
  }
  return true;
}

/// How a ray crosses a triangle, counter-clockwise seen from outside.
enum class Crossing { kNone, kExit, kEntry, kUncertain };

/// The ray from `origin` along `direction` against the triangle (a, b, c), Möller and
/// Trumbore's test. A hit closer to an edge or a corner than a billionth (barycentric),
/// a ray nearly in the triangle's plane or an origin on the triangle is uncertain: the
/// count then depends on rounding, so the caller casts another ray. Never throws.
Crossing RayCrossing(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                     const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Unit ray directions for counting a winding number, tried in turn where one grazes an
/// edge: no zero component (the slab test divides by them), away from the axes and
/// diagonals that meshes built on grids line their edges up with.
const std::array<Eigen::Vector3d, 4>& WindingRayDirections();

/// The rays along which a point inside buried skin looks for the way out (both colliders'
/// ProjectOut): the axes and the diagonals, turned a little off the directions that meshes
/// built on grids line their edges up with (a ray along an edge is not counted).
constexpr std::size_t kNumExitRays = 14;
const std::array<Eigen::Vector3d, kNumExitRays>& ExitRayDirections();

/// Where a point lies relative to a closed surface, from its closest surface point.
struct SurfaceSide {
  /// Distance to the closest point [m], negative inside.
  double signed_distance = 0.0;
  /// Unit outward normal at the point: the direction from the closest point to it
  /// (reversed inside), the distance field's gradient; the pseudonormal on the surface.
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
};

/// The side of `point` [m] given its closest surface point `closest` [m] and the unit
/// angle-weighted pseudonormal of the feature `closest` lies on: inside when the offset
/// points against it (Bærentzen & Aanæs 2005). Never throws.
SurfaceSide SideOf(const Eigen::Vector3d& point, const Eigen::Vector3d& closest,
                   const Eigen::Vector3d& pseudonormal);

/// Edge adjacency, connected pieces and angle-weighted pseudonormals of a triangle mesh.
/// The topology is fixed at construction; Update recomputes the normals for new vertex
/// positions. Triangles are counter-clockwise seen from outside.
class SurfacePseudonormals {
 public:
  /// Builds the edge adjacency and the pieces (sets of triangles connected over edges).
  /// Does not validate: indices must lie in [0, num_vertices). Edges used by one triangle
  /// (holes) or more than two (non-manifold) are counted, not refused; see
  /// num_open_edges().
  SurfacePseudonormals(int num_vertices, const std::vector<Eigen::Vector3i>& triangles);

  /// Recomputes face, edge and vertex pseudonormals for `vertices` (num_vertices×3) [m].
  /// With `vertex_normals` false the vertex pseudonormals are left out (three arc
  /// tangents per triangle, most of the cost) for the three-argument Of to compute the few
  /// needed. Never throws; never allocates. Precondition: vertices.rows() == num_vertices.
  void Update(const Points& vertices, bool vertex_normals = true);

  /// Unit pseudonormal of `feature` of triangle `triangle`: the face normal; for an edge
  /// the normalised sum of its two faces' normals (both have angle π); for a vertex the
  /// incident face normals weighted by their angle there, normalised. Precondition for a
  /// vertex: the last Update computed the vertex pseudonormals.
  Eigen::Vector3d Of(int triangle, TriangleFeature feature) const;
  /// The same, computing a vertex's pseudonormal from `vertices` (those of the last Update)
  /// when Update left them out: bit for bit the value Update would have given.
  Eigen::Vector3d Of(int triangle, TriangleFeature feature, const Points& vertices) const;
  /// The pseudonormal of vertex `vertex` for `vertices` (those of the last Update).
  Eigen::Vector3d VertexNormal(int vertex, const Points& vertices) const;
  /// The same from `vertices` alone, its triangles' normals computed here: for the few
  /// vertices a caller needs of a surface that moves, without an Update of all its faces.
  /// Bit for bit what VertexNormal gives after Update(vertices).
  Eigen::Vector3d VertexNormalOf(int vertex, const Points& vertices) const;
  const Eigen::Vector3d& face_normal(int triangle) const { return face_normals_[triangle]; }
  /// Twice the area of each triangle [m²] from the last Update.
  double double_area(int triangle) const { return double_areas_[triangle]; }

  int num_triangles() const { return static_cast<int>(triangles_.size()); }
  const std::vector<Eigen::Vector3i>& triangles() const { return triangles_; }
  /// The triangle across edge k (from corner k to corner k+1) of `triangle`, -1 for none.
  int neighbour(int triangle, int k) const { return neighbours_[triangle][k]; }
  /// Number of connected pieces and the piece of each triangle.
  int num_pieces() const { return num_pieces_; }
  int piece_of(int triangle) const { return pieces_[triangle]; }
  /// Edges used by exactly one triangle, or by more than two, or twice in the same
  /// direction (an orientation flip): zero for a closed, consistently oriented mesh.
  int num_open_edges() const { return num_open_edges_; }
  /// Describes the first such edge ("edge (3, 7) used by 1 triangle"), empty when none.
  const std::string& first_open_edge() const { return first_open_edge_; }

 private:
  void BuildAdjacency();
  void BuildPieces();
  /// VertexNormal (`own_faces` false: the face normals of the last Update) and
  /// VertexNormalOf (true: computed from `vertices`).
  Eigen::Vector3d AngleWeightedNormal(int vertex, const Points& vertices, bool own_faces) const;

  std::vector<Eigen::Vector3i> triangles_;
  std::vector<std::array<int, 3>> neighbours_;
  std::vector<int> pieces_;
  int num_pieces_ = 0;
  int num_open_edges_ = 0;
  std::string first_open_edge_;
  std::vector<Eigen::Vector3d> face_normals_;
  std::vector<double> double_areas_;
  std::vector<Eigen::Vector3d> vertex_normals_;
  bool has_vertex_normals_ = false;
  /// The corners (3 × triangle + k) at each vertex, in triangle order: vertex v's are
  /// [corner_start_[v], corner_start_[v + 1]) of corners_.
  std::vector<int> corner_start_;
  std::vector<int> corners_;
};

}  // namespace costume::sim
