#include "sim_core/avatar/clip.h"

#include <algorithm>
#include <cmath>

#include "sim_core/avatar/coordinate_bound.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

/// Joints a retargeting needs both skeletons to have, or the result is not a humanoid.
constexpr HAnimJoint kRequiredForRetargeting[] = {
    HAnimJoint::kHumanoidRoot, HAnimJoint::kLHip,      HAnimJoint::kRHip,
    HAnimJoint::kLKnee,        HAnimJoint::kRKnee,     HAnimJoint::kLShoulder,
    HAnimJoint::kRShoulder,    HAnimJoint::kLElbow,    HAnimJoint::kRElbow};

Eigen::Vector3d RestPosition(const Skeleton& skeleton, HAnimJoint joint) {
  return skeleton.rest_world()[skeleton.Find(joint)].translation();
}

/// The least hip spread and thigh a retargeting measures a skeleton by [m]: the facing is
/// taken across the hips and the root's travel scaled by the thighs, so a damaged file
/// whose offsets collapse either to a point would turn or scale every pose by 0/0.
constexpr double kMinMeasure = 1e-3;

/// Throws InputError (prefixed `where`) unless `skeleton`'s hips lie apart across the body
/// and its left thigh has a length, both at least kMinMeasure.
void RequireMeasurable(const Skeleton& skeleton, const std::string& where) {
  Eigen::Vector3d across =
      RestPosition(skeleton, HAnimJoint::kLHip) - RestPosition(skeleton, HAnimJoint::kRHip);
  across.y() = 0.0;
  const double thigh =
      (RestPosition(skeleton, HAnimJoint::kLHip) - RestPosition(skeleton, HAnimJoint::kLKnee))
          .norm();
  const auto refuse = [&](const std::string& finding, const std::string& use) {
    throw InputError(where + ": skeleton '" + skeleton.name() + "': " + finding +
                     " (allowed: at least " + FormatValue(kMinMeasure) + " m; " + use + ")");
  };
  if (!(across.norm() >= kMinMeasure)) {
    refuse("l_hip and r_hip are " + FormatValue(across.norm()) + " m apart across the body",
           "the facing is taken across the hips");
  }
  if (!(thigh >= kMinMeasure)) {
    refuse("l_hip to l_knee is " + FormatValue(thigh) + " m",
           "the root's travel is scaled by the thighs' ratio");
  }
}

/// The horizontal direction the skeleton faces in its rest pose: left hip minus right hip,
/// turned a quarter about +y (x left, y up, z forward).
Eigen::Vector3d Facing(const Skeleton& skeleton) {
  Eigen::Vector3d left =
      RestPosition(skeleton, HAnimJoint::kLHip) - RestPosition(skeleton, HAnimJoint::kRHip);
  left.y() = 0.0;
  return left.cross(Eigen::Vector3d::UnitY()).normalized();
}

double LegLength(const Skeleton& skeleton) {
  return (RestPosition(skeleton, HAnimJoint::kLHip) - RestPosition(skeleton, HAnimJoint::kLKnee))
             .norm() * 2.0;
}

/// The first H-Anim child of `joint` both skeletons have: where the bone points. The root
/// and the pelvis have none: their frames carry the whole body, whose direction the facing
/// alignment already matches (a rig whose root sits behind the spine, as MakeHuman's does,
/// would otherwise be tipped over by its root-to-spine direction).
std::optional<HAnimJoint> SharedChild(HAnimJoint joint, const Skeleton& a, const Skeleton& b) {
  if (joint == HAnimJoint::kHumanoidRoot || joint == HAnimJoint::kSacroiliac) return std::nullopt;
  for (HAnimJoint child : AllHAnimJoints()) {
    if (HAnimParent(child) != joint || a.Find(child) < 0 || b.Find(child) < 0) continue;
    // The spine's first child stands for the bone; the shoulders branch off it.
    if (joint == HAnimJoint::kVc7 && child != HAnimJoint::kSkullbase) continue;
    return child;
  }
  return std::nullopt;
}

/// Whether any H-Anim joint has `joint` as its parent.
bool HasHAnimChild(HAnimJoint joint) {
  for (HAnimJoint child : AllHAnimJoints()) {
    if (HAnimParent(child) == joint) return true;
  }
  return false;
}

}  // namespace

double Clip::duration() const {
  const double n = static_cast<double>(frames.size());
  return (loops ? n : std::max(0.0, n - 1.0)) * frame_time;
}

void ValidateClip(const Clip& clip) {
  const std::string where = "clip '" + clip.name + "'";
  if (!clip.skeleton) throw InputError(where + ": has no skeleton");
  if (clip.frames.empty()) throw InputError(where + ": has no frames");
  if (!(clip.frame_time >= kMinFrameTime && clip.frame_time <= kMaxFrameTime)) {
    throw InputError(where + ": frame_time " + FormatValue(clip.frame_time) + " s (allowed: [" +
                     FormatValue(kMinFrameTime) + ", " + FormatValue(kMaxFrameTime) + "])");
  }
  const std::size_t num_joints = clip.skeleton->num_joints();
  for (std::size_t f = 0; f < clip.frames.size(); ++f) {
    const Pose& pose = clip.frames[f];
    const std::string frame = where + ", frame " + std::to_string(f);
    if (pose.rotations.size() != num_joints) {
      throw InputError(frame + ": " + std::to_string(pose.rotations.size()) +
                       " joint rotations, skeleton has " + std::to_string(num_joints));
    }
    for (const Eigen::Quaterniond& q : pose.rotations) {
      if (!q.coeffs().allFinite() || q.norm() < 1e-9) {
        throw InputError(frame + ": non-finite or zero rotation");
      }
    }
    if (!pose.root_translation.allFinite() || !pose.orientation.coeffs().allFinite()) {
      throw InputError(frame + ": non-finite root translation or orientation");
    }
    RequireWithinReach(pose.root_translation, frame + ": root translation coordinate",
                       "the clip's origin");
  }
}

Eigen::Vector3d LoopTravel(const Clip& clip) {
  const int n = static_cast<int>(clip.frames.size());
  if (!clip.loops || n < 2) return Eigen::Vector3d::Zero();
  // Over a pass the root moves from frame 0 to frame n − 1 in n − 1 intervals, and on to
  // the next pass's frame 0 in one more at the same pace.
  Eigen::Vector3d travel = (clip.frames[n - 1].root_translation - clip.frames[0].root_translation) *
                           (static_cast<double>(n) / (n - 1));
  travel.y() = 0.0;  // up and down repeats; only the ground covered adds up
  return travel;
}

// Why the travel adds up: a looping walk or run that moves across the floor (DeepMimic's
// clips do) jumped back to its start at every wrap, 0.9 m in one frame, and the skirt it
// wore was left on the far side of the legs at 1,300 % strain.
void SampleClip(const Clip& clip, double t, Pose& out) {
  const int n = static_cast<int>(clip.frames.size());
  // A non-finite time would make the frame index undefined; show the first frame instead.
  double position = std::isfinite(t) ? t / clip.frame_time : 0.0;
  double passes = 0.0;
  if (clip.loops) {
    passes = std::floor(position / n);
    position -= passes * n;
    if (position >= n) position = 0.0, passes += 1.0;  // rounding at the wrap
  } else {
    position = std::clamp(position, 0.0, static_cast<double>(n - 1));
  }
  const int first = std::min(static_cast<int>(position), n - 1);
  const int second = clip.loops ? (first + 1) % n : std::min(first + 1, n - 1);
  InterpolatePoses(clip.frames[first], clip.frames[second], position - first, out);
  if (!clip.loops) return;
  const Eigen::Vector3d travel = LoopTravel(clip);
  // Between the last frame and the first of the next pass, the first's root is a pass on.
  const double wrapped = second < first ? position - first : 0.0;
  out.root_translation += (passes + wrapped) * travel;
}

Retargeter::Retargeter(std::shared_ptr<const Skeleton> source,
                       std::shared_ptr<const Skeleton> target)
    : source_(std::move(source)), target_(std::move(target)) {
  std::string missing;
  for (HAnimJoint joint : kRequiredForRetargeting) {
    if (source_->Find(joint) < 0 || target_->Find(joint) < 0) {
      missing += (missing.empty() ? "" : ", ") + std::string(HAnimName(joint));
    }
  }
  const std::string where =
      "retargeting skeleton '" + source_->name() + "' onto '" + target_->name() + "'";
  if (!missing.empty()) throw InputError(where + ": both must map the H-Anim joints " + missing);
  RequireMeasurable(*source_, where);
  RequireMeasurable(*target_, where);
  facing_.setFromTwoVectors(Facing(*source_), Facing(*target_));
  translation_scale_ = LegLength(*target_) / LegLength(*source_);

  const int n = target_->num_joints();
  source_of_target_.assign(n, -1);
  alignment_.assign(n, Eigen::Quaterniond::Identity());
  for (int j = 0; j < n; ++j) {
    const std::optional<HAnimJoint> hanim = target_->joint(j).hanim;
    if (!hanim || source_->Find(*hanim) < 0) continue;
    source_of_target_[j] = source_->Find(*hanim);
    // A joint without a bone of its own (hands, feet, head: no H-Anim child; or a bone of
    // zero length) keeps its parent's alignment, so its segment stays where the target's
    // rest pose puts it relative to the parent segment.
    const int parent = target_->joint(j).parent;
    if (parent >= 0 && !HasHAnimChild(*hanim)) alignment_[j] = alignment_[parent];
    const std::optional<HAnimJoint> child = SharedChild(*hanim, *source_, *target_);
    if (!child) continue;
    const Eigen::Vector3d target_bone =
        RestPosition(*target_, *child) - RestPosition(*target_, *hanim);
    const Eigen::Vector3d source_bone =
        facing_ * (RestPosition(*source_, *child) - RestPosition(*source_, *hanim));
    if (target_bone.norm() < 1e-9 || source_bone.norm() < 1e-9) {
      if (parent >= 0) alignment_[j] = alignment_[parent];
      continue;
    }
    alignment_[j].setFromTwoVectors(target_bone, source_bone);
  }
}

void Retargeter::Apply(const Pose& source_pose, Pose& target_pose) const {
  ComputeJointWorld(*source_, source_pose, source_world_);
  // The source's world frames include its placement (orientation); take it out here and
  // give it to the target's pose instead, or the target would be turned twice.
  const Eigen::Quaterniond unplace = source_pose.orientation.normalized().conjugate();
  const int n = target_->num_joints();
  target_pose.rotations.resize(n);
  target_world_.resize(n);
  const std::vector<Eigen::Isometry3d>& source_rest = source_->rest_world();
  const std::vector<Eigen::Isometry3d>& target_rest = target_->rest_world();
  for (int j = 0; j < n; ++j) {
    const Joint& joint = target_->joint(j);
    const Eigen::Quaterniond parent_world =
        joint.parent >= 0 ? target_world_[joint.parent] : Eigen::Quaterniond::Identity();
    const Eigen::Quaterniond rest_local(joint.rest_local.linear());
    const int s = source_of_target_[j];
    if (s < 0) {
      target_pose.rotations[j].setIdentity();
      target_world_[j] = parent_world * rest_local;
      continue;
    }
    // World rotation the source joint made relative to its rest, seen in the target's
    // facing frame, applied to the target's (bone-aligned) rest frame.
    const Eigen::Quaterniond delta =
        facing_ * unplace *
        Eigen::Quaterniond(source_world_[s].linear() * source_rest[s].linear().transpose()) *
        facing_.conjugate();
    target_world_[j] =
        (delta * alignment_[j] * Eigen::Quaterniond(target_rest[j].linear())).normalized();
    target_pose.rotations[j] =
        ((parent_world * rest_local).conjugate() * target_world_[j]).normalized();
  }
  target_pose.root_translation = Translation(source_pose);
  target_pose.orientation = (facing_ * source_pose.orientation * facing_.conjugate()).normalized();
}

}  // namespace costume::sim
