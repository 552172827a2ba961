#pragma once
/// @file
/// Keeping a clip's forearms out of the avatar's hips (AvatarMotionSettings::arm_spread).
/// Retargeting copies each bone's direction from the clip's performer, so a clip captured
/// on a body narrower at the hips than the avatar swings the avatar's forearms through its
/// own hips: Khronos' CesiumMan walking CMU's 02_02 had up to 41 forearm and hand vertices
/// inside or within 2 mm of the rest of his body in a frame, and the built-in skirt's
/// waistband, caught there, reached 656 % strain. Animators answer this with an "arm spread": each arm turned a few
/// degrees away from the body for the whole clip. FindArmSpread chooses the least such
/// angle per arm that keeps the forearm and hand a clearance off the rest of the body.

#include <array>
#include <memory>
#include <string>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/avatar_motion.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/scene/scene_description.h"

namespace costume::sim {

/// How far the forearm and hand are kept off the rest of the body [m]: room for cloth of
/// the usual thickness (a few mm) on both of them.
inline constexpr double kArmClearance = 0.01;

/// What FindArmSpread measured. Index 0 is the left arm, 1 the right.
struct ArmSpreadFit {
  /// False when nothing could be measured: no clip, or the avatar's mesh is not closed
  /// (inside is undefined); `angle` is then 0 and `why_not` says which.
  bool measured = false;
  std::string why_not;
  /// The spread per arm [rad] in [0, kMaxArmSpread].
  std::array<double, 2> angle{0.0, 0.0};
  /// Frames of the clip sampled (30 per second, at most kMaxArmSpreadSamples).
  int frames_sampled = 0;
  /// Sampled frames in which the arm's forearm or hand came nearer the rest of the body
  /// than kArmClearance, as retargeted and with the spread (skin that near in the posture,
  /// or still that near turned out kMaxAutoArmSpread, is not counted: FindArmSpread).
  std::array<int, 2> frames_near_before{0, 0};
  std::array<int, 2> frames_near_after{0, 0};
};

/// The most clip frames FindArmSpread samples (a long clip is sampled more sparsely).
inline constexpr int kMaxArmSpreadSamples = 600;

/// The most FindArmSpread turns an arm [rad] (15°): more changes the motion visibly, and
/// a scene may still ask for up to kMaxArmSpread.
inline constexpr double kMaxAutoArmSpread = 15.0 * 3.14159265358979323846 / 180.0;

/// The least spread per arm, in steps of 3° up to kMaxAutoArmSpread, with which no sampled
/// frame of `clip` (played as `settings` say, its own arm_spread ignored) brings that arm's
/// forearm or hand within kArmClearance of the rest of `avatar`'s body; where no angle
/// does, the one with the fewest such frames (the smallest of equals). A vertex is near
/// when the point kArmClearance outside it along its normal is inside the skinned body
/// (winding number, MeshDistance::Inside). Vertices near in the posture do not count, nor,
/// in a frame, those still near with the arm turned kMaxAutoArmSpread out (the arm's own
/// folds). Only a point within another segment's boxes, in the world and in the segment
/// joint's frame, is counted, and on a body of closed pieces only its winding in the pieces
/// with skin other than the arm's (a point inside the arm is not near the rest of the
/// body; a body of one piece is counted whole). Costs a skinning per sampled frame and,
/// once a point passes the boxes, the body's trees (78 ms on the built-in humanoid) and a
/// refit of them per pose tried: each frame near is tried from the spread the frames
/// before it needed, 0.01–0.02 s on the built-in clips (none near), 0.04–0.5 s on CMU's
/// clips (tools/arm_spread_bench; docs/assets.md). Never throws.
ArmSpreadFit FindArmSpread(const std::shared_ptr<const Avatar>& avatar,
                           const std::shared_ptr<const Clip>& clip,
                           const AvatarMotionSettings& settings);

/// The last spread FindArmSpread chose, kept for the next scene with the same avatar, clip
/// and motion: a STOP or a new fabric rebuilds the simulation from its scene, and the
/// search takes 0.01–0.5 s each time. Holds the avatar and clip weakly (a freed one never
/// matches a new one at its address).
class ArmSpreadMemo {
 public:
  /// FindArmSpread(avatar, clip, settings), or the answer of the last search when the
  /// avatar, clip and settings (all but their own arm_spread) are those it was made for.
  /// Never throws.
  const ArmSpreadFit& Find(const std::shared_ptr<const Avatar>& avatar,
                           const std::shared_ptr<const Clip>& clip,
                           const AvatarMotionSettings& settings);
  /// Searches run since construction [-].
  int num_searches() const { return num_searches_; }

 private:
  bool has_fit_ = false;
  std::weak_ptr<const Avatar> avatar_;
  std::weak_ptr<const Clip> clip_;
  AvatarMotionSettings settings_;
  ArmSpreadFit fit_;
  int num_searches_ = 0;
};

/// A change of the arms' spread asked for with a new posture (Simulation::SetPosture).
struct ArmSpreadRequest {
  enum class Kind {
    kKeep,   ///< the spread stays as it is
    kAuto,   ///< chosen for the clip in the new posture (FindArmSpread)
    kGiven,  ///< `angle`
  };
  Kind kind = Kind::kKeep;
  /// Per arm (left, right), for kGiven [rad] in [0, kMaxArmSpread].
  std::array<double, 2> angle{0.0, 0.0};
};

/// `spec` with the posture and arms' spread `request` asks for: what a rebuild of the
/// scene then plays. Never throws (the ranges are AvatarMotion's to check).
AvatarSpec WithPosture(const AvatarSpec& spec, const Pose& posture,
                       const ArmSpreadRequest& request);

/// The arms' spread once `request` is applied, as PlayedMotion chooses it for `posed` (the
/// scene's avatar in its new posture, WithPosture); `current` (what was chosen before) for
/// kKeep. Never throws.
ArmSpreadFit SpreadForPosture(const AvatarSpec& posed, const ArmSpreadRequest& request,
                              const ArmSpreadFit& current, ArmSpreadMemo& memo);

/// The motion `spec`'s avatar plays: spec.motion with the arms' spread that `memo` finds,
/// when spec.auto_arm_spread, or as the scene gives it. `fit` gets what was measured (for
/// a spread the scene gives: not measured, "as given, not chosen"). The simulation and the
/// GUI's copy of its scene both play this, so they show the same body. Never throws.
AvatarMotionSettings PlayedMotion(const AvatarSpec& spec, ArmSpreadMemo& memo,
                                  ArmSpreadFit& fit);

/// One line for logs: the spread per arm and why ("arms spread 9° (left) and 12° (right):
/// ...", "arms as retargeted: ...").
std::string DescribeArmSpread(const ArmSpreadFit& fit);

}  // namespace costume::sim
