#pragma once
/// @file
/// The built-in humanoid, made once per test program (about 6,400 vertices, tens of ms),
/// and a clip of it that needs the arms' spread (sim_core/scene/arm_spread.h).

#include <Eigen/Geometry>
#include <memory>
#include <numbers>

#include "sim_core/avatar/clip.h"
#include "sim_core/avatar/procedural_humanoid.h"

namespace costume::test {

inline const std::shared_ptr<const sim::Avatar>& Humanoid() {
  static const std::shared_ptr<const sim::Avatar> avatar = sim::MakeHumanoid();
  return avatar;
}

/// A clip of the humanoid's own skeleton holding the left arm `degrees` in towards the
/// body from its rest (20° out: procedural_humanoid.h), i.e. about −z at the shoulder.
inline std::shared_ptr<const sim::Clip> ArmInClip(double degrees) {
  auto clip = std::make_shared<sim::Clip>();
  clip->name = "arm in";
  clip->skeleton = Humanoid()->shared_skeleton();
  clip->frame_time = 0.5;
  clip->frames = {sim::RestPose(*clip->skeleton), sim::RestPose(*clip->skeleton)};
  const int shoulder = clip->skeleton->Find(sim::HAnimJoint::kLShoulder);
  for (sim::Pose& pose : clip->frames) {
    pose.rotations[shoulder] =
        Eigen::AngleAxisd(-degrees * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ());
  }
  return clip;
}

}  // namespace costume::test
