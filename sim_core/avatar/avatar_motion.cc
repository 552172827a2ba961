#include "sim_core/avatar/avatar_motion.h"

#include <algorithm>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

/// 3s² − 2s³: rises from 0 to 1 over s in [0, 1] with zero slope at both ends.
double Smoothstep(double s) { return s * s * (3.0 - 2.0 * s); }

void RequireArmSpread(const Avatar& avatar, const std::array<double, 2>& arm_spread) {
  for (std::size_t side = 0; side < 2; ++side) {
    const double angle = arm_spread[side];
    if (!(angle >= 0.0 && angle <= kMaxArmSpread)) {
      throw InputError("avatar '" + avatar.name() + "': arm spread (" +
                       (side == 0 ? "left" : "right") + ") = " + std::to_string(angle) +
                       " rad: allowed 0 to " + std::to_string(kMaxArmSpread) + " rad (" +
                       std::to_string(static_cast<int>(kMaxArmSpreadDegrees)) + "°)");
    }
  }
}

}  // namespace

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
  RequireArmSpread(*avatar_, settings_.arm_spread);
  if (clip_) {
    ValidateClip(*clip_);
    retargeter_.emplace(clip_->skeleton, avatar_->shared_skeleton());
    start_translation_ = ClipTranslation(0.0);
    PrepareArmSpreads();
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

void AvatarMotion::SetPosture(const Pose& posture, const std::array<double, 2>& arm_spread) {
  RequireArmSpread(*avatar_, arm_spread);
  SetPosture(posture);  // throws before anything changes
  settings_.arm_spread = arm_spread;
  arm_spreads_.clear();
  if (clip_) PrepareArmSpreads();
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
    SpreadArms(retargeted_);
    // After the blend the clip's own translation, which Apply gave.
    if (BlendFraction(clip_time) < 1.0) retargeted_.root_translation = EasedTranslation(clip_time);
    // The clip's own placement is relative; the designer's placement stays.
    retargeted_.root_translation = settings_.posture.orientation * retargeted_.root_translation +
                                   settings_.posture.root_translation;
    retargeted_.orientation = settings_.posture.orientation * retargeted_.orientation;
    // Joint angles blend linearly (easing them made the tight MakeHuman suit's worst frames
    // worse in the benchmark: docs/assets.md); the translation starts from the posture's
    // already (EasedTranslation).
    InterpolatePoses(settings_.posture, retargeted_, BlendFraction(clip_time), pose_);
    pose_.root_translation = retargeted_.root_translation;
  }
  if (has_previous_ && posture_blend < 1.0) {
    InterpolatePoses(previous_, pose_, std::max(0.0, posture_blend), blended_);
    std::swap(pose_, blended_);
  }
  ComputeJointWorld(avatar_->skeleton(), pose_, joint_world_);
  SkinVertices(*avatar_, joint_world_, skinning_, vertices_);
}

double AvatarMotion::BlendFraction(double clip_time) const {
  return settings_.blend_time > 0.0 ? std::min(1.0, clip_time / settings_.blend_time) : 1.0;
}

Eigen::Vector3d AvatarMotion::ClipTranslation(double clip_time) {
  SampleClip(*clip_, clip_time, translation_pose_);
  return retargeter_->Translation(translation_pose_);
}

Eigen::Vector3d AvatarMotion::EasedTranslation(double clip_time) {
  // Blended linearly at the clip's own pace, from a body standing still to a clip already
  // walking, the hips moved at up to twice the clip's speed at the blend's end and then
  // dropped to it in one step (CesiumMan walking CMU's 02_02: 2.0 then 1.1 m/s; the
  // skirt's waistband then stretched 134 %). Over the blend the clip's translation runs on
  // a clock τ = T (6s³ − 8s⁴ + 3s⁵) instead, s the fraction of the blend T elapsed: it
  // starts at rest without a jolt, speeds up to at most 1.51 times the clip's pace (at most
  // 4 v / T, where v is the clip's speed) and meets the clip's own time, pace and
  // acceleration at the blend's end, so the motion after the blend is the clip's exactly.
  // The clip's own offset at its start is blended in meanwhile. Called during the blend
  // only (s < 1).
  const double s = BlendFraction(clip_time);
  const double clock = settings_.blend_time * s * s * s * (6.0 - 8.0 * s + 3.0 * s * s);
  return ClipTranslation(clock) - (1.0 - Smoothstep(s)) * start_translation_;
}

void AvatarMotion::PrepareArmSpreads() {
  const Skeleton& skeleton = avatar_->skeleton();
  const int left = skeleton.Find(HAnimJoint::kLShoulder);
  const int right = skeleton.Find(HAnimJoint::kRShoulder);
  const int root = skeleton.Find(HAnimJoint::kHumanoidRoot);
  if (left < 0 || right < 0 || root < 0) return;  // the Retargeter needs them: not reached
  const std::vector<Eigen::Isometry3d>& rest = skeleton.rest_world();
  // The trunk's axes in the rest pose: up from the root to between the shoulders, lateral
  // from the right shoulder to the left. Spreading the left arm turns a hanging arm
  // (−up) towards +lateral: about lateral × up; the right one about the opposite axis.
  const Eigen::Vector3d l = rest[left].translation(), r = rest[right].translation();
  const Eigen::Vector3d up = (0.5 * (l + r) - rest[root].translation()).normalized();
  Eigen::Vector3d lateral = l - r;
  lateral -= lateral.dot(up) * up;
  if (!(lateral.norm() > 1e-9) || !up.allFinite()) return;
  const Eigen::Vector3d axis = lateral.normalized().cross(up);
  const int shoulders[2] = {left, right};
  for (int side = 0; side < 2; ++side) {
    if (settings_.arm_spread[side] == 0.0) continue;
    ArmSpread spread;
    spread.shoulder = shoulders[side];
    spread.parent = skeleton.joint(spread.shoulder).parent;
    const Eigen::Vector3d world_axis = side == 0 ? axis : Eigen::Vector3d(-axis);
    spread.axis_in_parent =
        spread.parent < 0 ? world_axis
                          : Eigen::Vector3d(rest[spread.parent].linear().transpose() * world_axis);
    spread.angle = settings_.arm_spread[side];
    arm_spreads_.push_back(spread);
  }
}

void AvatarMotion::SpreadArms(Pose& pose) {
  if (arm_spreads_.empty()) return;
  ComputeJointWorld(avatar_->skeleton(), pose, spread_world_);
  for (const ArmSpread& spread : arm_spreads_) {
    // The axis follows the trunk (the shoulder's parent); turning the arm about it at the
    // shoulder is, in the shoulder's own frame, a rotation after the clip's.
    const Eigen::Matrix3d parent = spread.parent < 0
                                       ? Eigen::Matrix3d(Eigen::Matrix3d::Identity())
                                       : Eigen::Matrix3d(spread_world_[spread.parent].linear());
    const Eigen::Vector3d local =
        spread_world_[spread.shoulder].linear().transpose() * (parent * spread.axis_in_parent);
    Eigen::Quaterniond& q = pose.rotations[spread.shoulder];
    q = (q * Eigen::Quaterniond(Eigen::AngleAxisd(spread.angle, local.normalized()))).normalized();
  }
}

}  // namespace costume::sim
