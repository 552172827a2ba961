#pragma once
/// @file
/// A skinned avatar (skeleton + surface mesh + skin weights) and linear blend skinning.

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "sim_core/avatar/pose.h"
#include "sim_core/avatar/skeleton.h"
#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// Up to this many joints influence one vertex; importers keep the largest weights and
/// renormalise.
inline constexpr int kMaxInfluences = 4;

struct AvatarData {
  std::string name = "avatar";
  std::shared_ptr<const Skeleton> skeleton;
  /// Surface vertices in the rest pose, world coordinates, y up (n×3) [m].
  Points rest_vertices;
  /// Triangles, counter-clockwise seen from outside the body.
  std::vector<Eigen::Vector3i> triangles;
  /// Per vertex (n×kMaxInfluences): joint indices (-1 for an unused slot) and their weights
  /// (>= 0, summing to 1 per vertex).
  Eigen::Matrix<int, Eigen::Dynamic, kMaxInfluences, Eigen::RowMajor> influence_joints;
  Eigen::Matrix<double, Eigen::Dynamic, kMaxInfluences, Eigen::RowMajor> influence_weights;
  /// Where the asset came from and under what licence (free text, may be empty).
  std::string provenance;
};

class Avatar {
 public:
  /// Validates and builds. Throws InputError naming the avatar, the field, the offending
  /// vertex/triangle and the allowed range for: no skeleton; no vertices; non-finite
  /// positions, or a coordinate beyond kMaxCoordinate; a triangle index out of range; an
  /// influence joint out of range; negative weights or weights not summing to 1 within 1e-6
  /// after the importer's normalisation.
  static std::shared_ptr<const Avatar> Create(AvatarData data);

  const std::string& name() const { return data_.name; }
  const Skeleton& skeleton() const { return *data_.skeleton; }
  const std::shared_ptr<const Skeleton>& shared_skeleton() const { return data_.skeleton; }
  const Points& rest_vertices() const { return data_.rest_vertices; }
  const std::vector<Eigen::Vector3i>& triangles() const { return data_.triangles; }
  int num_vertices() const { return static_cast<int>(data_.rest_vertices.rows()); }
  const AvatarData& data() const { return data_; }
  /// The H-Anim segment each vertex belongs to: that of its largest-weight joint (nullopt
  /// when no ancestor of it is mapped onto H-Anim).
  const std::vector<std::optional<HAnimJoint>>& vertex_segments() const { return segments_; }
  /// Each joint's rest world frame inverted (the bind matrices of skinning).
  const std::vector<Eigen::Isometry3d>& inverse_bind() const { return inverse_bind_; }

 private:
  explicit Avatar(AvatarData data);
  AvatarData data_;
  std::vector<std::optional<HAnimJoint>> segments_;
  std::vector<Eigen::Isometry3d> inverse_bind_;
};

/// Whether `a` and `b` have the same skin at rest: as many vertices, each within 1 µm (two
/// avatars imported from the same body file).
bool SameRestSkin(const Avatar& a, const Avatar& b);

/// Linear blend skinning: the vertices of `avatar` for joint frames `joint_world` (from
/// ComputeJointWorld) into `vertices` (resized to n×3). `skinning` is scratch for the
/// per-joint skinning transforms. Never throws; allocates only if `vertices` or `skinning`
/// has the wrong size.
void SkinVertices(const Avatar& avatar, const std::vector<Eigen::Isometry3d>& joint_world,
                  std::vector<Eigen::Isometry3d>& skinning, Points& vertices);

}  // namespace costume::sim
