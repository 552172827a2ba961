#pragma once
/// @file
/// Exact signed distance from points to a closed, animated triangle mesh (the avatar's
/// skin): the penetration measure of collision tests and benchmarks, and the yardstick of
/// the fast superquadric method (paper §4). Triangles sit in Bullet btDbvt trees built on
/// the first pose (or copied from an earlier build of the same mesh: reused_trees()) and
/// refitted bottom up when the mesh moves. Query's sign comes from
/// angle-weighted pseudonormals (Bærentzen & Aanæs 2005), right at edges and vertices of a
/// mesh that does not pass through itself; the penetration measures decide inside by the
/// winding number, which stays right where skinning folds the skin through itself.

#include <Eigen/Geometry>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/collision/surface_geometry.h"

namespace costume::sim {

/// The answer to one distance query.
struct SurfaceDistance {
  /// Signed distance to the surface [m]: negative inside, +inf when no surface lies within
  /// the search radius (inside or out).
  double signed_distance = std::numeric_limits<double>::infinity();
  /// Closest surface point [m] (meaningless when signed_distance is +inf).
  Eigen::Vector3d closest_point = Eigen::Vector3d::Zero();
  /// Unit outward normal at the query: the direction from the closest point to the query
  /// (reversed inside), which is the distance field's gradient; the pseudonormal of the
  /// closest feature when the query lies on the surface.
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
  /// Triangle holding the closest point (-1 for none), the feature of it and the
  /// barycentric weights of its corners [-].
  int triangle = -1;
  TriangleFeature feature = TriangleFeature::kFace;
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();
};

/// Penetration statistics of a point set, for tests and benchmarks.
struct PenetrationStats {
  int num_points = 0;
  /// Points strictly inside the body (signed distance < 0).
  int num_inside = 0;
  /// Deepest penetration [m] (0 when none is inside).
  double max_depth = 0.0;
  /// 99th percentile of the depths of the points inside [m] (nearest rank; 0 when none).
  double p99_depth = 0.0;
};

/// Signed distance to a closed triangle mesh made of one or more closed pieces; the body
/// is their union (a point inside any piece is inside, and its distance is the smallest
/// over the pieces, so the depth inside is that of the piece it penetrates most).
class MeshDistance {
 public:
  /// `vertices` (n×3) [m], `triangles` counter-clockwise seen from outside. Throws
  /// InputError naming `name` and the offending vertex, triangle or edge for: no
  /// triangles; a non-finite vertex; a vertex index outside [0, n); an edge not shared
  /// by exactly two triangles running it in opposite directions (the mesh is not closed
  /// and consistently oriented, so inside and outside are undefined).
  MeshDistance(std::string name, const Points& vertices, std::vector<Eigen::Vector3i> triangles);
  ~MeshDistance();
  MeshDistance(const MeshDistance&) = delete;
  MeshDistance& operator=(const MeshDistance&) = delete;

  /// Moves the mesh to `vertices` (n×3) [m], same topology: refits the trees' boxes bottom
  /// up (their structure stays that of the first pose); the face normals follow at the
  /// next Query (Inside needs none: the arm-spread search asks only that). Returns false,
  /// doing nothing, when the row count differs from the mesh's. Never throws; never
  /// allocates.
  bool Update(const Points& vertices);

  /// The surface point closest to `point` [m] within `max_radius` [m] >= 0, with its
  /// signed distance and normal. Never throws; never allocates after the first call. Not
  /// thread-safe (one scratch stack per object; the face normals brought up to date).
  SurfaceDistance Query(const Eigen::Vector3d& point, double max_radius) const;

  /// Query(point, max_radius).signed_distance.
  double SignedDistance(const Eigen::Vector3d& point, double max_radius) const {
    return Query(point, max_radius).signed_distance;
  }

  /// Whether `point` is inside the body: its winding number in some piece is at least 1,
  /// counted exactly as the signed crossings of a ray from it (exits − entries; a ray
  /// through an edge or a vertex is replaced by another). Unlike the pseudonormal sign of
  /// the nearest feature, this holds where the skin passes through itself: linear blend
  /// skinning folds MakeHuman's crotch at dihedral angles near 180°, and there the nearest
  /// edge's pseudonormal put a point 4.9 mm inside that lay outside (docs/collision.md,
  /// "The penetration oracle"). Where skin is turned inside out (winding −1) is outside.
  /// Never throws; never allocates after the first call. Not thread-safe.
  bool Inside(const Eigen::Vector3d& point) const { return Inside(point, nullptr); }
  /// The same counting only the pieces `pieces` marks (num_pieces() flags; null: all).
  bool Inside(const Eigen::Vector3d& point, const std::vector<char>* pieces) const;
  /// The piece of triangle `triangle` (its index in the triangles given), in
  /// [0, num_pieces()).
  int piece_of(int triangle) const { return normals_.piece_of(triangle); }

  /// The penetration depth of `point` [m]: its distance to the nearest surface when
  /// Inside(point), else 0. A point farther than `max_radius` [m] from every surface is
  /// missed (depth 0): choose it above any depth you need to see, e.g. half the body's
  /// thickness. Never throws; never allocates after the first call.
  double PenetrationDepth(const Eigen::Vector3d& point, double max_radius) const;

  /// Per point of `points` (m×3) [m] its PenetrationDepth [m] into `depths` (resized to m).
  void PenetrationDepths(const Points& points, double max_radius,
                         std::vector<double>& depths) const;

  /// Count, maximum and 99th percentile of the penetrations of `points` (m×3) [m],
  /// searched within `max_radius` [m] as in PenetrationDepths.
  PenetrationStats MeasurePenetration(const Points& points, double max_radius) const;

  /// The deepest penetration of `points` (m×3) [m] (0 when none is inside).
  double MaxPenetration(const Points& points, double max_radius) const {
    return MeasurePenetration(points, max_radius).max_depth;
  }

  int num_vertices() const { return num_vertices_; }
  /// Whether the trees are clones of those of an earlier MeshDistance of the same mesh (the
  /// same vertices and triangles), kept when it was built (meshes of 2,000 triangles and
  /// more; the last two): they answer as if built here.
  bool reused_trees() const { return reused_trees_; }
  int num_triangles() const { return normals_.num_triangles(); }
  int num_pieces() const { return normals_.num_pieces(); }

 private:
  struct Trees;  // the Bullet trees, kept out of this header (Bullet links privately)

  /// Builds the trees over the current vertices and keeps a copy for a later build of the
  /// same mesh.
  void BuildTrees();
  void Refit(const Points& vertices);
  /// The face normals for the current vertices, computed once after each Update.
  void UpdateNormals() const;
  void NearestInPiece(int piece, const Eigen::Vector3d& point, double max_radius,
                      SurfaceDistance& best) const;
  /// The signed crossings of the ray from `point` along `direction` with piece `piece`
  /// (its winding number there); false when the ray passes too near an edge, a vertex or
  /// a triangle's plane to count.
  bool WindingInPiece(int piece, const Eigen::Vector3d& point, const Eigen::Vector3d& direction,
                      int& winding) const;

  std::string name_;
  int num_vertices_ = 0;
  Points vertices_;
  /// Mutable: Query brings the normals up to date (UpdateNormals), like its scratch stack.
  mutable SurfacePseudonormals normals_;
  mutable bool normals_current_ = false;
  std::unique_ptr<Trees> trees_;
  bool reused_trees_ = false;
};

}  // namespace costume::sim
