#pragma once
/// @file
/// An immutable joint hierarchy in its rest pose.

#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_core/avatar/hanim.h"

namespace costume::sim {

struct Joint {
  /// The name in the source file ("LeftUpLeg", "upperarm01.L"); unique within a skeleton.
  std::string name;
  /// Index of the parent joint, smaller than this joint's own index; -1 for a root.
  int parent = -1;
  /// The joint's frame relative to its parent's frame in the rest pose (world frame for a
  /// root) [m]; a rigid transform.
  Eigen::Isometry3d rest_local = Eigen::Isometry3d::Identity();
  /// The H-Anim joint this one is, if any (at most one joint per H-Anim id).
  std::optional<HAnimJoint> hanim;
};

class Skeleton {
 public:
  /// Validates and builds. Throws InputError naming `name`, the joint and the field for: no
  /// joints, an empty or repeated name, a parent index not smaller than the joint's own, a
  /// non-rigid or non-finite rest transform, a rest offset with a coordinate beyond
  /// kMaxCoordinate, an H-Anim id used twice.
  static std::shared_ptr<const Skeleton> Create(std::string name, std::vector<Joint> joints);

  const std::string& name() const { return name_; }
  int num_joints() const { return static_cast<int>(joints_.size()); }
  const std::vector<Joint>& joints() const { return joints_; }
  const Joint& joint(int index) const { return joints_[index]; }
  /// Each joint's frame in world coordinates in the rest pose [m].
  const std::vector<Eigen::Isometry3d>& rest_world() const { return rest_world_; }
  /// Index of the joint named `name` (exact match), or -1.
  int FindByName(const std::string& name) const;
  /// Index of the joint mapped onto `joint`, or -1 when the skeleton has none.
  int Find(HAnimJoint joint) const { return hanim_index_[static_cast<int>(joint)]; }
  /// The H-Anim segment a vertex weighted to joint `index` belongs to: the nearest joint at or
  /// above it that is mapped onto H-Anim, or, where none is (a rig whose deform bones hang
  /// from helper bones, as Rigify's do), the mapped joint whose bone (to its nearest mapped
  /// descendants) passes nearest to it in the rest pose; nullopt only for a skeleton with no
  /// mapped joint.
  std::optional<HAnimJoint> HAnimSegmentOf(int index) const;

 private:
  Skeleton(std::string name, std::vector<Joint> joints);
  std::string name_;
  std::vector<Joint> joints_;
  std::vector<Eigen::Isometry3d> rest_world_;
  /// HAnimSegmentOf per joint, found once (FindSegments).
  std::vector<std::optional<HAnimJoint>> segment_of_;
  void FindSegments();
  std::array<int, kNumHAnimJoints> hanim_index_{};
};

}  // namespace costume::sim
