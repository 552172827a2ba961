#pragma once
/// @file
/// Animation clips: poses of a source skeleton sampled at a fixed rate, and their
/// retargeting onto any other skeleton through the H-Anim joints both are mapped onto.

#include <memory>
#include <string>
#include <vector>

#include "sim_core/avatar/pose.h"
#include "sim_core/avatar/skeleton.h"

namespace costume::sim {

/// "basic" (stand, walk, run, jump, kick) or "choreography".
enum class ClipCategory { kBasic, kChoreography };

/// Bounds of a clip's frame time [s]. Motion capture records at most a few kHz; a file
/// claiming more (1e-300 s a frame) holds a whole clip in no time, which plays as one pose
/// jumping at random. Ten seconds a frame is a slide show, not an animation.
constexpr double kMinFrameTime = 1e-4;
constexpr double kMaxFrameTime = 10.0;

struct Clip {
  std::string name;
  ClipCategory category = ClipCategory::kBasic;
  /// The skeleton the frames are poses of (the source file's, or the built-in humanoid's).
  std::shared_ptr<const Skeleton> skeleton;
  /// Time between frames [s], within [kMinFrameTime, kMaxFrameTime].
  double frame_time = 1.0 / 30.0;
  /// Poses of `skeleton`, at least one.
  std::vector<Pose> frames;
  /// A looping clip wraps from its last frame back to its first (which must then follow it
  /// without a jump); otherwise sampling holds the last frame.
  bool loops = true;
  std::string provenance;

  /// Length [s]: frames × frame_time when looping (the last frame blends back into the
  /// first), (frames − 1) × frame_time otherwise.
  double duration() const;
};

/// Validates a clip: throws InputError naming the clip, the field and the allowed range
/// for no skeleton, no frames, frame_time outside [kMinFrameTime, kMaxFrameTime], a frame
/// whose rotation count differs from the skeleton's joint count, non-finite values, a root
/// translation beyond kMaxCoordinate.
void ValidateClip(const Clip& clip);

/// The ground a looping clip's root covers in one pass [m] (LoopTravel × passes is added to
/// the root when sampling): the horizontal move from its first frame to its last, carried on
/// at the same pace to the next pass's first frame. Zero for a clip that does not loop.
Eigen::Vector3d LoopTravel(const Clip& clip);

/// The clip's pose at time t [s] (any t; wrapped or held as `loops` says), interpolated
/// between neighbouring frames. A looping clip that travels goes on travelling: each pass
/// starts where the last one ended (its root moved by LoopTravel per pass), as a walk on a
/// treadmill would not. Never throws; allocates only if `out` is too small.
void SampleClip(const Clip& clip, double t, Pose& out);

/// Maps poses of one skeleton onto another through their H-Anim joints (paper §6):
/// each mapped target joint takes the world-space rotation its source twin made relative to
/// the source rest pose, after the target's rest bone direction has been aligned with the
/// source's (so a T-pose clip drives an A-pose avatar with the arms where they belong).
/// Unmapped target joints keep their rest rotation relative to their parent. The root
/// translation is scaled by the ratio of the two skeletons' leg lengths (twice hip to knee).
class Retargeter {
 public:
  /// Precomputes the alignment. Throws InputError if the two skeletons share fewer than
  /// the root plus both hips, knees, shoulders and elbows.
  Retargeter(std::shared_ptr<const Skeleton> source, std::shared_ptr<const Skeleton> target);

  /// `source_pose` of the source skeleton → `target_pose` of the target. Never throws;
  /// allocates only on the first call (scratch kept in the object, so one Retargeter must
  /// not be used from two threads at once).
  void Apply(const Pose& source_pose, Pose& target_pose) const;

  /// The target's root translation for `source_pose` (Apply's, alone) [m].
  Eigen::Vector3d Translation(const Pose& source_pose) const {
    return facing_ * source_pose.root_translation * translation_scale_;
  }

  const Skeleton& source() const { return *source_; }
  const Skeleton& target() const { return *target_; }

 private:
  std::shared_ptr<const Skeleton> source_;
  std::shared_ptr<const Skeleton> target_;
  /// Per target joint: its source twin (-1 if none) and the rest alignment rotation.
  std::vector<int> source_of_target_;
  std::vector<Eigen::Quaterniond> alignment_;
  /// Yaw turning the source's facing direction onto the target's.
  Eigen::Quaterniond facing_ = Eigen::Quaterniond::Identity();
  double translation_scale_ = 1.0;
  mutable std::vector<Eigen::Isometry3d> source_world_;
  mutable std::vector<Eigen::Quaterniond> target_world_;
};

}  // namespace costume::sim
