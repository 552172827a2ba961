#include "sim_core/avatar/pose.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace costume::sim {

Pose RestPose(const Skeleton& skeleton) {
  Pose pose;
  pose.rotations.assign(skeleton.num_joints(), Eigen::Quaterniond::Identity());
  return pose;
}

Eigen::Quaterniond PostureRotation(const Eigen::Vector3d& degrees) {
  const Eigen::Vector3d radians = degrees * (std::numbers::pi / 180.0);
  return Eigen::AngleAxisd(radians.x(), Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(radians.y(), Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(radians.z(), Eigen::Vector3d::UnitZ());
}

Eigen::Vector3d PostureDegrees(const Eigen::Quaterniond& rotation) {
  // R = Rx(a) Ry(b) Rz(c): its first row is (cos b cos c, −cos b sin c, sin b) and its last
  // column (sin b, −sin a cos b, cos a cos b).
  const Eigen::Matrix3d r = rotation.normalized().toRotationMatrix();
  const double b = std::asin(std::clamp(r(0, 2), -1.0, 1.0));
  double a = 0.0, c = 0.0;
  if (std::abs(r(0, 2)) < 1.0 - 1e-12) {
    a = std::atan2(-r(1, 2), r(2, 2));
    c = std::atan2(-r(0, 1), r(0, 0));
  } else {
    // cos b = 0: R's lower left block is the turn about x by a ± c; all of it goes to x.
    a = std::atan2(r(2, 1), r(1, 1));
  }
  return Eigen::Vector3d(a, b, c) * (180.0 / std::numbers::pi);
}

void ComputeJointWorld(const Skeleton& skeleton, const Pose& pose,
                       std::vector<Eigen::Isometry3d>& world) {
  const int n = skeleton.num_joints();
  world.resize(n);
  Eigen::Isometry3d placement = Eigen::Isometry3d::Identity();
  placement.linear() = pose.orientation.normalized().toRotationMatrix();
  for (int i = 0; i < n; ++i) {
    const Joint& joint = skeleton.joint(i);
    Eigen::Isometry3d local = joint.rest_local;
    local.linear() = local.linear() * pose.rotations[i].normalized().toRotationMatrix();
    if (joint.parent >= 0) {
      world[i] = world[joint.parent] * local;
    } else {
      local.translation() += pose.root_translation;
      world[i] = placement * local;
    }
  }
}

void InterpolatePoses(const Pose& a, const Pose& b, double t, Pose& out) {
  out.rotations.resize(a.rotations.size());
  for (std::size_t i = 0; i < a.rotations.size(); ++i) {
    out.rotations[i] = a.rotations[i].slerp(t, b.rotations[i]);
  }
  out.root_translation = (1.0 - t) * a.root_translation + t * b.root_translation;
  out.orientation = a.orientation.slerp(t, b.orientation);
}

}  // namespace costume::sim
