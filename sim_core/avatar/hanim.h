#pragma once
/// @file
/// The H-Anim (ISO/IEC 19774) joints every avatar and clip is mapped onto (paper §6,
/// DESIGN.md). Imported skeletons keep their own joints; those that correspond to one of
/// these carry its id, and clips are retargeted from one skeleton to another through them.

#include <array>
#include <optional>
#include <string_view>

namespace costume::sim {

/// The joints of H-Anim's level of articulation 1 plus vc7. The body segment a joint moves
/// (its child segment) shares its id: kLKnee moves the left calf, kVl5 the torso, and so on.
enum class HAnimJoint : int {
  kHumanoidRoot = 0,
  kSacroiliac,     // pelvis
  kLHip,           // left thigh
  kLKnee,          // left calf
  kLTalocrural,    // left foot (H-Anim 1.1: l_ankle)
  kRHip,
  kRKnee,
  kRTalocrural,
  kVl5,            // torso, lumbar spine to the base of the neck
  kVc7,            // neck
  kSkullbase,      // head
  kLShoulder,      // left upper arm
  kLElbow,         // left forearm
  kLRadiocarpal,   // left hand (H-Anim 1.1: l_wrist)
  kRShoulder,
  kRElbow,
  kRRadiocarpal,
};
inline constexpr int kNumHAnimJoints = 17;

/// The H-Anim 2.0 name ("l_talocrural").
std::string_view HAnimName(HAnimJoint joint);

/// Parses an H-Anim 2.0 or 1.1 name ("l_ankle", "l_wrist", "HumanoidRoot"), ignoring case;
/// nullopt for anything else.
std::optional<HAnimJoint> ParseHAnimName(std::string_view name);

/// The joint's parent in the H-Anim hierarchy (nullopt for the root):
/// humanoid_root → sacroiliac → hips → knees → ankles; humanoid_root → vl5 → vc7 →
/// skullbase and shoulders → elbows → wrists.
std::optional<HAnimJoint> HAnimParent(HAnimJoint joint);

/// The mirror-image joint (l_ ↔ r_; itself for the spine).
HAnimJoint HAnimMirror(HAnimJoint joint);

/// All joints in order, parents before children.
const std::array<HAnimJoint, kNumHAnimJoints>& AllHAnimJoints();

}  // namespace costume::sim
