#pragma once
/// @file
/// The avatar as a scene plays it (paper §6, mode A): garments are placed around its rest
/// pose, so during the first half of the fitting time it moves from the rest pose into the
/// designer's posture and holds it for the second half while the garment settles; then the
/// clip, retargeted onto it, blends in. Skinned every step.

#include <array>
#include <memory>
#include <optional>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/avatar/pose.h"

namespace costume::sim {

struct AvatarMotionSettings {
  /// The posture the garment is fitted in and the clip starts from (rotations empty = rest
  /// pose), with the avatar's placement (root_translation, orientation), both reached from
  /// the rest pose over the first half of fit_time.
  Pose posture;
  /// Time the avatar holds the posture before the clip starts [s] >= 0: the fitting.
  double fit_time = 0.5;
  /// Time over which the clip blends in from the posture [s] >= 0.
  double blend_time = 0.3;
  /// Per arm (left, right): the angle by which the clip's arm is turned away from the body
  /// about the trunk's forward axis at the shoulder [rad] in [0, kMaxArmSpread]; 0 plays
  /// the clip as retargeted. A clip captured on a body narrower at the hips than the
  /// avatar swings the forearms through the avatar's hips (the retargeting copies the
  /// bones' directions), and cloth caught there is torn (arm_spread.h finds the angle).
  std::array<double, 2> arm_spread{0.0, 0.0};
};

/// The largest arm spread a scene may ask for [degrees], and in radians.
inline constexpr double kMaxArmSpreadDegrees = 30.0;
inline constexpr double kMaxArmSpread = kMaxArmSpreadDegrees * 3.14159265358979323846 / 180.0;

class AvatarMotion {
 public:
  /// `clip` may be null (the avatar holds its posture). Throws InputError when the clip
  /// cannot be retargeted onto the avatar (Retargeter) or the posture has the wrong number
  /// of rotations.
  AvatarMotion(std::shared_ptr<const Avatar> avatar, std::shared_ptr<const Clip> clip,
               AvatarMotionSettings settings);

  /// Poses, forward kinematics and skinning at scene time t [s]. With `posture_blend` in
  /// [0, 1) after a SetPosture, the pose is the spherical blend from the pose the avatar had
  /// when SetPosture was called (weight 1 − blend) to the pose at t with the new posture
  /// (weight blend): the caller moves the body gradually, so the cloth can follow. 1 (the
  /// default) is the plain pose at t, bit for bit as before any SetPosture. Never throws;
  /// allocates only on the first call.
  void Evaluate(double t, double posture_blend = 1.0);

  /// Replaces the designer's posture (rotations and placement; the clip, fit and blend times
  /// stay) and remembers the current pose as the start of the transition Evaluate blends
  /// over. Throws InputError when `posture` does not have one rotation per joint or holds a
  /// non-finite value.
  void SetPosture(const Pose& posture);
  /// As SetPosture(posture), and the arms' spread becomes `arm_spread` (per arm [rad] in
  /// [0, kMaxArmSpread]; AvatarMotionSettings::arm_spread), reached over the same
  /// transition. Throws InputError, changing nothing, for a spread out of range as well.
  void SetPosture(const Pose& posture, const std::array<double, 2>& arm_spread);

  const Avatar& avatar() const { return *avatar_; }
  const std::shared_ptr<const Avatar>& shared_avatar() const { return avatar_; }
  const Pose& pose() const { return pose_; }
  /// Joint frames in world coordinates at the last Evaluate.
  const std::vector<Eigen::Isometry3d>& joint_world() const { return joint_world_; }
  /// Skinned vertices (n×3) [m] at the last Evaluate.
  const Points& vertices() const { return vertices_; }
  /// Joint frames of the posture (the fitting pose), computed once.
  const std::vector<Eigen::Isometry3d>& posture_world() const { return posture_world_; }
  const AvatarMotionSettings& settings() const { return settings_; }

 private:
  std::shared_ptr<const Avatar> avatar_;
  std::shared_ptr<const Clip> clip_;
  std::optional<Retargeter> retargeter_;
  AvatarMotionSettings settings_;
  Pose rest_, clip_pose_, retargeted_, pose_;
  /// The pose when SetPosture was last called, and a scratch pose for the blend.
  Pose previous_, blended_;
  bool has_previous_ = false;
  /// Per arm with a spread: the shoulder joint, its parent, and the spread's axis in the
  /// parent's frame (fixed to the trunk, so the arm is spread whatever the trunk does).
  struct ArmSpread {
    int shoulder = -1, parent = -1;
    Eigen::Vector3d axis_in_parent = Eigen::Vector3d::UnitZ();
    double angle = 0.0;
  };
  std::vector<ArmSpread> arm_spreads_;
  /// Scratch pose for the clip's translation (EasedTranslation), and that translation at
  /// the clip's start, found once.
  Pose translation_pose_;
  Eigen::Vector3d start_translation_ = Eigen::Vector3d::Zero();
  double BlendFraction(double clip_time) const;
  Eigen::Vector3d ClipTranslation(double clip_time);
  Eigen::Vector3d EasedTranslation(double clip_time);
  void PrepareArmSpreads();
  void SpreadArms(Pose& pose);
  std::vector<Eigen::Isometry3d> joint_world_, posture_world_, skinning_, spread_world_;
  Points vertices_;
};

}  // namespace costume::sim
