#pragma once
/// @file
/// Which joint of an imported skeleton is which H-Anim joint (sim_core/avatar/hanim.h), per
/// skeleton family: every exporter names its joints its own way, and the Retargeter
/// (sim_core/avatar/clip.h) can only map clips between skeletons whose joints carry H-Anim
/// ids. The tables were read from the real files (docs/assets.md lists them).

#include <string>
#include <string_view>
#include <vector>

#include "sim_core/avatar/hanim.h"
#include "sim_core/avatar/skeleton.h"

namespace costume::assets {

/// A naming convention for humanoid joints.
enum class SkeletonFamily {
  kUnknown = 0,
  /// H-Anim's own names, 2.0 or 1.1 ("humanoid_root", "l_hip", "HumanoidRoot", "l_ankle").
  kHAnim,
  /// CMU mocap as converted from ASF by cgspeed, and Mixamo without prefix: Hips,
  /// LHipJoint, LeftUpLeg, LeftLeg, LeftFoot, LowerBack, Spine, Neck, Head, LeftShoulder
  /// (the clavicle), LeftArm, LeftForeArm, LeftHand.
  kCmuCgspeed,
  /// CMU mocap as converted for Poser / Second Life (CMU 02_02.bvh): hip, abdomen, chest,
  /// neck, head, lCollar, lShldr, lForeArm, lHand, lButtock, lThigh, lShin, lFoot.
  kPoserBvh,
  /// Biovision-style BVH (CMU 10_01.bvh): Hips, LeftHip, LeftKnee, LeftAnkle, Chest,
  /// CS_BVH, Neck, Head, LeftCollar, LeftShoulder (the upper arm), LeftElbow, LeftWrist.
  kBiovisionBvh,
  /// MakeHuman's default skeleton (default.mhskel, 163 bones): root, spine05..01,
  /// neck01..03, head, clavicle.L, shoulder01.L, upperarm01.L, lowerarm01.L, wrist.L,
  /// pelvis.L, upperleg01.L, lowerleg01.L, foot.L, …
  kMakeHumanDefault,
  /// The rig of MakeHuman's BVH animations (walk1_mhskel.bvh): Root, Hips, Spine1..3, Neck,
  /// Head, Clavicle_L, UpArm_L, LoArm_L, Hand_L, UpLeg_L, LoLeg_L, Foot_L, Toe_L.
  kMakeHumanBvh,
  /// Khronos' CesiumMan glTF sample: Skeleton_torso_joint_1, leg_joint_L_1,
  /// Skeleton_arm_joint_L__4_, …
  kCesiumMan,
  /// DeepMimic's humanoid3d character: root, chest, neck, right_hip, right_knee, …
  kDeepMimic,
  /// Mixamo rigs: "mixamorig:Hips", "mixamorig:LeftUpLeg", … (any "prefix:" namespace).
  kMixamo,
  /// Blender's human metarig (Blender 2.8 and later) and the deform bones Rigify generates
  /// from it ("DEF-" dropped): spine (the hips), spine.001 … spine.006 (the head), thigh.L,
  /// shin.L, foot.L, shoulder.L (the clavicle), upper_arm.L, forearm.L, hand.L.
  kBlender,
  /// Unreal Engine's mannequins (UE4; UE5's Manny and Quinn): root (on the floor), pelvis,
  /// spine_01 …, neck_01, head, thigh_l, calf_l, foot_l, clavicle_l, upperarm_l,
  /// lowerarm_l, hand_l.
  kUnreal,
  /// 3ds Max's Biped, whatever the biped's name ("Bip01", "Bip001", "Bip02", …, all starting
  /// "Bip"): Bip01, Bip01 Pelvis, Bip01 Spine,
  /// Bip01 Neck, Bip01 Head, Bip01 L Thigh, Bip01 L Calf, Bip01 L Foot, Bip01 L Clavicle,
  /// Bip01 L UpperArm, Bip01 L Forearm, Bip01 L Hand.
  kMaxBiped,
  /// VRoid Studio's VRM avatars: J_Bip_C_Hips, J_Bip_C_Spine, J_Bip_C_Chest, J_Bip_C_Neck,
  /// J_Bip_C_Head, J_Bip_L_UpperLeg, J_Bip_L_LowerLeg, J_Bip_L_Foot, J_Bip_L_Shoulder (the
  /// clavicle), J_Bip_L_UpperArm, J_Bip_L_LowerArm, J_Bip_L_Hand.
  kVRoid,
  /// Daz 3D's Genesis 3 and 8 figures: hip, pelvis, abdomenLower, neckLower, head,
  /// lThighBend, lShin, lFoot, lCollar, lShldrBend, lForearmBend, lHand (… Twist bones beside).
  /// Genesis 1 and 2 are named as Poser's figures (kPoserBvh).
  kDazGenesis,
  /// Reallusion's Character Creator 3 and 4 (and AccuRIG, ActorCore): CC_Base_Hip,
  /// CC_Base_Pelvis, CC_Base_Waist, CC_Base_NeckTwist01, CC_Base_Head, CC_Base_L_Thigh,
  /// CC_Base_L_Calf, CC_Base_L_Foot, CC_Base_L_Clavicle, CC_Base_L_Upperarm,
  /// CC_Base_L_Forearm, CC_Base_L_Hand.
  kCharacterCreator,
};

/// The family's name for messages and docs ("CMU BVH (cgspeed)").
std::string_view FamilyName(SkeletonFamily family);

/// One row of a mapping table: the H-Anim joint and the family's names for it, in order of
/// preference (the first one a skeleton has wins). Names compare ignoring case.
struct FamilyMapping {
  sim::HAnimJoint hanim;
  std::vector<std::string_view> names;
};

/// The mapping table of `family` (empty for kUnknown; kHAnim maps through
/// sim::ParseHAnimName instead and returns an empty table too).
const std::vector<FamilyMapping>& MappingTable(SkeletonFamily family);

/// The H-Anim joint that `joint_name` is in `family`, or nullopt. For kMixamo, a namespace
/// prefix ending in ':' ("mixamorig:", "mixamorig1:") is ignored; for kBlender, Rigify's
/// "DEF-"; for kMaxBiped, the biped's name before the first space ("Bip01 "; the name alone
/// is the biped's root).
/// Note: a table row with several names maps only the first present in a skeleton; this
/// function answers for one name alone and so accepts any of them.
std::optional<sim::HAnimJoint> LookUpJoint(SkeletonFamily family, std::string_view joint_name);

/// The family whose table maps the most joints of `joint_names` (ties: the earlier
/// enumerator). kUnknown when no family maps at least the retargeting minimum (root plus
/// both hips, knees, shoulders, elbows: 9 joints).
SkeletonFamily DetectFamily(const std::vector<std::string>& joint_names);

/// Sets Joint::hanim on `joints` from `family`'s table (each H-Anim id on at most one joint:
/// for each row, the first name in the row's order that one of the joints has). Clears any
/// id already set. Returns the number of joints mapped.
int ApplyFamily(SkeletonFamily family, std::vector<sim::Joint>& joints);

/// DetectFamily on the joints' names, then ApplyFamily; returns the family found (joints
/// are left unmapped for kUnknown).
SkeletonFamily MapToHAnim(std::vector<sim::Joint>& joints);

}  // namespace costume::assets
