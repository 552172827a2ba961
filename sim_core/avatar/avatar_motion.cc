#include "sim_core/avatar/avatar_motion.h"

#include <algorithm>

#include "sim_core/common/input_error.h"

namespace costume::sim {

AvatarMotion::AvatarMotion(std::shared_ptr<const Avatar> avatar, std::shared_ptr<const Clip> clip,
                           AvatarMotionSettings settings)
    : avatar_(std::move(avatar)), clip_(std::move(clip)), settings_(std::move(settings)) {
  const int n = avatar_->skeleton().num_joints();
  if (settings_.posture.rotations.empty()) {
    settings_.posture.rotations.assign(n, Eigen::Quaterniond::Identity());
  }
  if (static_cast<int>(settings_.posture.rotations.size()) != n) {
    throw InputError("avatar '" + avatar_->name() + "': posture has " +
                     std::to_string(settings_.posture.rotations.size()) +
                     " joint rotations, the skeleton has " + std::to_string(n));
  }
  RequireNonNegative("avatar.fit_time", settings_.fit_time, "s");
  RequireNonNegative("avatar.blend_time", settings_.blend_time, "s");
  if (clip_) {
    ValidateClip(*clip_);
    retargeter_.emplace(clip_->skeleton, avatar_->shared_skeleton());
  }
  rest_ = RestPose(avatar_->skeleton());
  ComputeJointWorld(avatar_->skeleton(), settings_.posture, posture_world_);
  pose_ = settings_.posture;
  Evaluate(0.0);
}

void AvatarMotion::SetPosture(const Pose& posture) {
  const int n = avatar_->skeleton().num_joints();
  if (static_cast<int>(posture.rotations.size()) != n) {
    throw InputError("avatar '" + avatar_->name() + "': posture has " +
                     std::to_string(posture.rotations.size()) + " joint rotations, the skeleton has " +
                     std::to_string(n));
  }
  bool finite = posture.root_translation.allFinite() && posture.orientation.coeffs().allFinite();
  for (const Eigen::Quaterniond& q : posture.rotations) finite = finite && q.coeffs().allFinite();
  if (!finite) {
    throw InputError("avatar '" + avatar_->name() + "': posture holds a non-finite value");
  }
  previous_ = pose_;
  has_previous_ = true;
  settings_.posture = posture;
  ComputeJointWorld(avatar_->skeleton(), settings_.posture, posture_world_);
}

void AvatarMotion::Evaluate(double t, double posture_blend) {
  const double clip_time = t - settings_.fit_time;
  const double reach_time = 0.5 * settings_.fit_time;
  if (t < reach_time) {
    InterpolatePoses(rest_, settings_.posture, std::max(0.0, t) / reach_time, pose_);
  } else if (!clip_ || clip_time <= 0.0) {
    pose_ = settings_.posture;
  } else {
    SampleClip(*clip_, clip_time, clip_pose_);
    retargeter_->Apply(clip_pose_, retargeted_);
    // The clip's own placement is relative; the designer's placement stays.
    retargeted_.root_translation = settings_.posture.orientation * retargeted_.root_translation +
                                   settings_.posture.root_translation;
    retargeted_.orientation = settings_.posture.orientation * retargeted_.orientation;
    const double blend =
        settings_.blend_time > 0.0 ? std::min(1.0, clip_time / settings_.blend_time) : 1.0;
    InterpolatePoses(settings_.posture, retargeted_, blend, pose_);
  }
  if (has_previous_ && posture_blend < 1.0) {
    InterpolatePoses(previous_, pose_, std::max(0.0, posture_blend), blended_);
    std::swap(pose_, blended_);
  }
  ComputeJointWorld(avatar_->skeleton(), pose_, joint_world_);
  SkinVertices(*avatar_, joint_world_, skinning_, vertices_);
}

}  // namespace costume::sim
