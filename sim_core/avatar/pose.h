#pragma once
/// @file
/// A posture of a skeleton, and the joint frames it puts in the world (forward kinematics).

#include <Eigen/Geometry>
#include <vector>

#include "sim_core/avatar/skeleton.h"

namespace costume::sim {

/// Joint angles plus the avatar's placement: everything a clip frame, or the designer
/// posing the avatar before fitting (paper §6), sets.
struct Pose {
  /// Per joint (Skeleton::num_joints() entries): rotation relative to the rest pose, in the
  /// joint's own rest frame, so the joint's frame relative to its parent is
  /// rest_local · rotation. Identity everywhere is the rest pose.
  std::vector<Eigen::Quaterniond> rotations;
  /// Offset of the root joints from their rest positions, in world coordinates [m].
  Eigen::Vector3d root_translation = Eigen::Vector3d::Zero();
  /// Orientation of the whole avatar about the world origin, applied last [-].
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

/// The rest pose of `skeleton`.
Pose RestPose(const Skeleton& skeleton);

/// Fills `world` (resized to num_joints) with each joint's frame in world coordinates for
/// `pose`. Never throws; allocates only if `world` is too small.
/// Precondition: pose.rotations.size() == skeleton.num_joints().
void ComputeJointWorld(const Skeleton& skeleton, const Pose& pose,
                       std::vector<Eigen::Isometry3d>& world);

/// Largest magnitude of a posture's angles, each joint angle and the heading [degrees]: a
/// turn and more is a typing error, which a readable message serves better than a pose.
inline constexpr double kMaxPostureDegrees = 360.0;

/// The rotation a designer's posture gives a joint: `degrees` about the joint's rest x, y
/// and z axes, applied in that order (the scene file's [avatar.posture], the server's
/// SET_POSTURE, the GUI's posture panel).
Eigen::Quaterniond PostureRotation(const Eigen::Vector3d& degrees);

/// The angles PostureRotation takes to give `rotation` [degrees]: about y within
/// [−90, 90], about x and z within [−180, 180] (at ±90 about y, where only x + z or x − z is
/// determined, all of it about x). For a panel showing a posture it did not set.
Eigen::Vector3d PostureDegrees(const Eigen::Quaterniond& rotation);

/// Spherical interpolation between two poses of one skeleton (t in [0, 1]).
void InterpolatePoses(const Pose& a, const Pose& b, double t, Pose& out);

}  // namespace costume::sim
