#include "assets/skeleton_families.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <optional>

namespace costume::assets {
namespace {

using sim::HAnimJoint;
using J = sim::HAnimJoint;

/// The joints sim::Retargeter needs on both skeletons: a family that cannot map these is
/// no use for retargeting, so detection does not settle for it.
constexpr int kRetargetingMinimum = 9;

bool EqualIgnoringCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

/// "mixamorig:LeftArm" → "LeftArm"; names without a namespace are returned unchanged.
std::string_view StripNamespace(std::string_view name) {
  const std::size_t colon = name.rfind(':');
  return colon == std::string_view::npos ? name : name.substr(colon + 1);
}

/// `name` without `prefix` (compared ignoring case) when it starts so and goes on.
std::string_view StripPrefix(std::string_view name, std::string_view prefix) {
  return name.size() > prefix.size() && EqualIgnoringCase(name.substr(0, prefix.size()), prefix)
             ? name.substr(prefix.size())
             : name;
}

/// "Bip01 L Thigh" → "L Thigh": a Biped's bones carry its name ("Bip01", "Bip001", or one
/// the user gave it) before their own. The biped's root is the name alone: "Bip01" for any.
std::string_view StripBipedName(std::string_view name) {
  if (!EqualIgnoringCase(name.substr(0, 3), "bip")) return name;
  const std::size_t space = name.find(' ');
  return space == std::string_view::npos ? std::string_view("Bip01") : name.substr(space + 1);
}

// The tables. Left and right are the character's own (checked against the files' rest
// positions: the left side lies at +x for a character facing +z, y up).

/// cgspeed's CMU conversion and Mixamo share these names; "LeftShoulder" is the clavicle.
const std::vector<FamilyMapping> kCmuCgspeedTable = {
    {J::kHumanoidRoot, {"Hips"}},
    {J::kLHip, {"LeftUpLeg"}},
    {J::kLKnee, {"LeftLeg"}},
    {J::kLTalocrural, {"LeftFoot"}},
    {J::kRHip, {"RightUpLeg"}},
    {J::kRKnee, {"RightLeg"}},
    {J::kRTalocrural, {"RightFoot"}},
    {J::kVl5, {"LowerBack", "Spine"}},
    {J::kVc7, {"Neck"}},
    {J::kSkullbase, {"Head"}},
    {J::kLShoulder, {"LeftArm"}},
    {J::kLElbow, {"LeftForeArm"}},
    {J::kLRadiocarpal, {"LeftHand"}},
    {J::kRShoulder, {"RightArm"}},
    {J::kRElbow, {"RightForeArm"}},
    {J::kRRadiocarpal, {"RightHand"}},
};

/// CMU 02_02.bvh: lButtock/rButtock sit between the hip and the thighs and are not mapped.
const std::vector<FamilyMapping> kPoserBvhTable = {
    {J::kHumanoidRoot, {"hip"}},
    {J::kLHip, {"lThigh"}},
    {J::kLKnee, {"lShin"}},
    {J::kLTalocrural, {"lFoot"}},
    {J::kRHip, {"rThigh"}},
    {J::kRKnee, {"rShin"}},
    {J::kRTalocrural, {"rFoot"}},
    {J::kVl5, {"abdomen"}},
    {J::kVc7, {"neck"}},
    {J::kSkullbase, {"head"}},
    {J::kLShoulder, {"lShldr"}},
    {J::kLElbow, {"lForeArm"}},
    {J::kLRadiocarpal, {"lHand"}},
    {J::kRShoulder, {"rShldr"}},
    {J::kRElbow, {"rForeArm"}},
    {J::kRRadiocarpal, {"rHand"}},
};

/// CMU 10_01.bvh: "LeftShoulder" is the upper arm here, "LeftCollar" the clavicle.
const std::vector<FamilyMapping> kBiovisionBvhTable = {
    {J::kHumanoidRoot, {"Hips"}},
    {J::kLHip, {"LeftHip"}},
    {J::kLKnee, {"LeftKnee"}},
    {J::kLTalocrural, {"LeftAnkle"}},
    {J::kRHip, {"RightHip"}},
    {J::kRKnee, {"RightKnee"}},
    {J::kRTalocrural, {"RightAnkle"}},
    {J::kVl5, {"Chest"}},
    {J::kVc7, {"Neck"}},
    {J::kSkullbase, {"Head"}},
    {J::kLShoulder, {"LeftShoulder"}},
    {J::kLElbow, {"LeftElbow"}},
    {J::kLRadiocarpal, {"LeftWrist"}},
    {J::kRShoulder, {"RightShoulder"}},
    {J::kRElbow, {"RightElbow"}},
    {J::kRRadiocarpal, {"RightWrist"}},
};

/// default.mhskel: the thigh, arm and forearm are split in two (…01 bends, …02 twists);
/// the …01 bone is the joint. pelvis.L/R are two bones, so no single sacroiliac.
const std::vector<FamilyMapping> kMakeHumanDefaultTable = {
    {J::kHumanoidRoot, {"root"}},
    {J::kLHip, {"upperleg01.L"}},
    {J::kLKnee, {"lowerleg01.L"}},
    {J::kLTalocrural, {"foot.L"}},
    {J::kRHip, {"upperleg01.R"}},
    {J::kRKnee, {"lowerleg01.R"}},
    {J::kRTalocrural, {"foot.R"}},
    {J::kVl5, {"spine04"}},
    {J::kVc7, {"neck01"}},
    {J::kSkullbase, {"head"}},
    {J::kLShoulder, {"upperarm01.L"}},
    {J::kLElbow, {"lowerarm01.L"}},
    {J::kLRadiocarpal, {"wrist.L"}},
    {J::kRShoulder, {"upperarm01.R"}},
    {J::kRElbow, {"lowerarm01.R"}},
    {J::kRRadiocarpal, {"wrist.R"}},
};

/// walk1_mhskel.bvh: "__UpLeg_L" and the like are offset helpers without a bone.
const std::vector<FamilyMapping> kMakeHumanBvhTable = {
    {J::kHumanoidRoot, {"Root"}},
    {J::kSacroiliac, {"Hips"}},
    {J::kLHip, {"UpLeg_L"}},
    {J::kLKnee, {"LoLeg_L"}},
    {J::kLTalocrural, {"Foot_L"}},
    {J::kRHip, {"UpLeg_R"}},
    {J::kRKnee, {"LoLeg_R"}},
    {J::kRTalocrural, {"Foot_R"}},
    {J::kVl5, {"Spine1"}},
    {J::kVc7, {"Neck"}},
    {J::kSkullbase, {"Head"}},
    {J::kLShoulder, {"UpArm_L"}},
    {J::kLElbow, {"LoArm_L"}},
    {J::kLRadiocarpal, {"Hand_L"}},
    {J::kRShoulder, {"UpArm_R"}},
    {J::kRElbow, {"LoArm_R"}},
    {J::kRRadiocarpal, {"Hand_R"}},
};

/// CesiumMan.glb: the left arm chain counts down (__4_ shoulder, __3_ elbow, __2_ wrist),
/// the right one up (R shoulder, R__2_ elbow, R__3_ wrist); leg_joint_*_5 is the toe.
const std::vector<FamilyMapping> kCesiumManTable = {
    {J::kHumanoidRoot, {"Skeleton_torso_joint_1"}},
    {J::kLHip, {"leg_joint_L_1"}},
    {J::kLKnee, {"leg_joint_L_2"}},
    {J::kLTalocrural, {"leg_joint_L_3"}},
    {J::kRHip, {"leg_joint_R_1"}},
    {J::kRKnee, {"leg_joint_R_2"}},
    {J::kRTalocrural, {"leg_joint_R_3"}},
    {J::kVl5, {"Skeleton_torso_joint_2"}},
    {J::kVc7, {"Skeleton_neck_joint_1"}},
    {J::kSkullbase, {"Skeleton_neck_joint_2"}},
    {J::kLShoulder, {"Skeleton_arm_joint_L__4_"}},
    {J::kLElbow, {"Skeleton_arm_joint_L__3_"}},
    {J::kLRadiocarpal, {"Skeleton_arm_joint_L__2_"}},
    {J::kRShoulder, {"Skeleton_arm_joint_R"}},
    {J::kRElbow, {"Skeleton_arm_joint_R__2_"}},
    {J::kRRadiocarpal, {"Skeleton_arm_joint_R__3_"}},
};

/// humanoid3d.txt: the "neck" joint sits at shoulder height and carries the head.
const std::vector<FamilyMapping> kDeepMimicTable = {
    {J::kHumanoidRoot, {"root"}},
    {J::kLHip, {"left_hip"}},
    {J::kLKnee, {"left_knee"}},
    {J::kLTalocrural, {"left_ankle"}},
    {J::kRHip, {"right_hip"}},
    {J::kRKnee, {"right_knee"}},
    {J::kRTalocrural, {"right_ankle"}},
    {J::kVl5, {"chest"}},
    {J::kVc7, {"neck"}},
    {J::kLShoulder, {"left_shoulder"}},
    {J::kLElbow, {"left_elbow"}},
    {J::kLRadiocarpal, {"left_wrist"}},
    {J::kRShoulder, {"right_shoulder"}},
    {J::kRElbow, {"right_elbow"}},
    {J::kRRadiocarpal, {"right_wrist"}},
};

/// Blender's human metarig: "spine" is the hips bone, its chain goes on to the head
/// (spine.006); "shoulder.L" is the clavicle. Rigify's generated rig deforms the skin with
/// copies of these bones named "DEF-…" (TableName drops the prefix); its control (no
/// prefix, other names), ORG- and MCH- bones are not mapped.
const std::vector<FamilyMapping> kBlenderTable = {
    {J::kHumanoidRoot, {"spine"}},
    {J::kLHip, {"thigh.L"}},
    {J::kLKnee, {"shin.L"}},
    {J::kLTalocrural, {"foot.L"}},
    {J::kRHip, {"thigh.R"}},
    {J::kRKnee, {"shin.R"}},
    {J::kRTalocrural, {"foot.R"}},
    {J::kVl5, {"spine.001"}},
    {J::kVc7, {"spine.004"}},
    {J::kSkullbase, {"spine.006"}},
    {J::kLShoulder, {"upper_arm.L"}},
    {J::kLElbow, {"forearm.L"}},
    {J::kLRadiocarpal, {"hand.L"}},
    {J::kRShoulder, {"upper_arm.R"}},
    {J::kRElbow, {"forearm.R"}},
    {J::kRRadiocarpal, {"hand.R"}},
};

/// Unreal's mannequins: "root" lies on the floor under the pelvis and carries root motion;
/// the pelvis is the body's root joint. The twist bones (thigh_twist_01_l, …) are not mapped.
const std::vector<FamilyMapping> kUnrealTable = {
    {J::kHumanoidRoot, {"pelvis"}},
    {J::kLHip, {"thigh_l"}},
    {J::kLKnee, {"calf_l"}},
    {J::kLTalocrural, {"foot_l"}},
    {J::kRHip, {"thigh_r"}},
    {J::kRKnee, {"calf_r"}},
    {J::kRTalocrural, {"foot_r"}},
    {J::kVl5, {"spine_01"}},
    {J::kVc7, {"neck_01"}},
    {J::kSkullbase, {"head"}},
    {J::kLShoulder, {"upperarm_l"}},
    {J::kLElbow, {"lowerarm_l"}},
    {J::kLRadiocarpal, {"hand_l"}},
    {J::kRShoulder, {"upperarm_r"}},
    {J::kRElbow, {"lowerarm_r"}},
    {J::kRRadiocarpal, {"hand_r"}},
};

/// 3ds Max's Biped, its names without the biped's (StripBipedName): the biped's root
/// sits at the pelvis, above the "Pelvis" bone.
const std::vector<FamilyMapping> kMaxBipedTable = {
    {J::kHumanoidRoot, {"Bip01"}},
    {J::kSacroiliac, {"Pelvis"}},
    {J::kLHip, {"L Thigh"}},
    {J::kLKnee, {"L Calf"}},
    {J::kLTalocrural, {"L Foot"}},
    {J::kRHip, {"R Thigh"}},
    {J::kRKnee, {"R Calf"}},
    {J::kRTalocrural, {"R Foot"}},
    {J::kVl5, {"Spine"}},
    {J::kVc7, {"Neck"}},
    {J::kSkullbase, {"Head"}},
    {J::kLShoulder, {"L UpperArm"}},
    {J::kLElbow, {"L Forearm"}},
    {J::kLRadiocarpal, {"L Hand"}},
    {J::kRShoulder, {"R UpperArm"}},
    {J::kRElbow, {"R Forearm"}},
    {J::kRRadiocarpal, {"R Hand"}},
};

/// VRoid Studio: "J_Bip_" bones form the humanoid ("C" centre, "L", "R"); "J_Sec_" (hair,
/// skirt) and "J_Adj_" (face) bones are not mapped.
const std::vector<FamilyMapping> kVRoidTable = {
    {J::kHumanoidRoot, {"J_Bip_C_Hips"}},
    {J::kLHip, {"J_Bip_L_UpperLeg"}},
    {J::kLKnee, {"J_Bip_L_LowerLeg"}},
    {J::kLTalocrural, {"J_Bip_L_Foot"}},
    {J::kRHip, {"J_Bip_R_UpperLeg"}},
    {J::kRKnee, {"J_Bip_R_LowerLeg"}},
    {J::kRTalocrural, {"J_Bip_R_Foot"}},
    {J::kVl5, {"J_Bip_C_Spine"}},
    {J::kVc7, {"J_Bip_C_Neck"}},
    {J::kSkullbase, {"J_Bip_C_Head"}},
    {J::kLShoulder, {"J_Bip_L_UpperArm"}},
    {J::kLElbow, {"J_Bip_L_LowerArm"}},
    {J::kLRadiocarpal, {"J_Bip_L_Hand"}},
    {J::kRShoulder, {"J_Bip_R_UpperArm"}},
    {J::kRElbow, {"J_Bip_R_LowerArm"}},
    {J::kRRadiocarpal, {"J_Bip_R_Hand"}},
};

/// Daz's Genesis 3 and 8: a limb's first bone is split into a bend and a twist bone, the
/// bend bone is the joint; "hip" carries the pelvis, the spine and the thighs' parent
/// "pelvis".
const std::vector<FamilyMapping> kDazGenesisTable = {
    {J::kHumanoidRoot, {"hip"}},
    {J::kSacroiliac, {"pelvis"}},
    {J::kLHip, {"lThighBend"}},
    {J::kLKnee, {"lShin"}},
    {J::kLTalocrural, {"lFoot"}},
    {J::kRHip, {"rThighBend"}},
    {J::kRKnee, {"rShin"}},
    {J::kRTalocrural, {"rFoot"}},
    {J::kVl5, {"abdomenLower"}},
    {J::kVc7, {"neckLower"}},
    {J::kSkullbase, {"head"}},
    {J::kLShoulder, {"lShldrBend"}},
    {J::kLElbow, {"lForearmBend"}},
    {J::kLRadiocarpal, {"lHand"}},
    {J::kRShoulder, {"rShldrBend"}},
    {J::kRElbow, {"rForearmBend"}},
    {J::kRRadiocarpal, {"rHand"}},
};

/// Reallusion's Character Creator: CC_Base_BoneRoot on the floor, CC_Base_Hip at the hips
/// above CC_Base_Pelvis (the thighs' parent) and CC_Base_Waist (the spine's).
const std::vector<FamilyMapping> kCharacterCreatorTable = {
    {J::kHumanoidRoot, {"CC_Base_Hip"}},
    {J::kSacroiliac, {"CC_Base_Pelvis"}},
    {J::kLHip, {"CC_Base_L_Thigh"}},
    {J::kLKnee, {"CC_Base_L_Calf"}},
    {J::kLTalocrural, {"CC_Base_L_Foot"}},
    {J::kRHip, {"CC_Base_R_Thigh"}},
    {J::kRKnee, {"CC_Base_R_Calf"}},
    {J::kRTalocrural, {"CC_Base_R_Foot"}},
    {J::kVl5, {"CC_Base_Waist"}},
    {J::kVc7, {"CC_Base_NeckTwist01"}},
    {J::kSkullbase, {"CC_Base_Head"}},
    {J::kLShoulder, {"CC_Base_L_Upperarm"}},
    {J::kLElbow, {"CC_Base_L_Forearm"}},
    {J::kLRadiocarpal, {"CC_Base_L_Hand"}},
    {J::kRShoulder, {"CC_Base_R_Upperarm"}},
    {J::kRElbow, {"CC_Base_R_Forearm"}},
    {J::kRRadiocarpal, {"CC_Base_R_Hand"}},
};

const std::vector<FamilyMapping> kEmptyTable;

/// Every family in detection order.
constexpr std::array<SkeletonFamily, 15> kFamilies = {
    SkeletonFamily::kHAnim,           SkeletonFamily::kCmuCgspeed, SkeletonFamily::kPoserBvh,
    SkeletonFamily::kBiovisionBvh,    SkeletonFamily::kMakeHumanDefault,
    SkeletonFamily::kMakeHumanBvh,    SkeletonFamily::kCesiumMan,  SkeletonFamily::kDeepMimic,
    SkeletonFamily::kMixamo,          SkeletonFamily::kBlender,    SkeletonFamily::kUnreal,
    SkeletonFamily::kMaxBiped,        SkeletonFamily::kVRoid,      SkeletonFamily::kDazGenesis,
    SkeletonFamily::kCharacterCreator};

/// The name as the family's table spells it: without Mixamo's namespace, Rigify's "DEF-"
/// or the Biped's name.
std::string_view TableName(SkeletonFamily family, std::string_view name) {
  switch (family) {
    case SkeletonFamily::kMixamo: return StripNamespace(name);
    case SkeletonFamily::kBlender: return StripPrefix(name, "DEF-");
    case SkeletonFamily::kMaxBiped: return StripBipedName(name);
    default: return name;
  }
}

/// For each H-Anim joint, the index in `names` of the joint `family` maps onto it (-1).
std::array<int, sim::kNumHAnimJoints> Assign(SkeletonFamily family,
                                             const std::vector<std::string>& names) {
  std::array<int, sim::kNumHAnimJoints> assigned;
  assigned.fill(-1);
  if (family == SkeletonFamily::kHAnim) {
    for (int i = 0; i < static_cast<int>(names.size()); ++i) {
      const std::optional<HAnimJoint> joint = sim::ParseHAnimName(names[i]);
      if (joint && assigned[static_cast<int>(*joint)] < 0) assigned[static_cast<int>(*joint)] = i;
    }
    return assigned;
  }
  for (const FamilyMapping& row : MappingTable(family)) {
    for (std::string_view candidate : row.names) {
      const auto found = std::find_if(names.begin(), names.end(), [&](const std::string& n) {
        return EqualIgnoringCase(TableName(family, n), candidate);
      });
      if (found != names.end()) {
        assigned[static_cast<int>(row.hanim)] = static_cast<int>(found - names.begin());
        break;
      }
    }
  }
  return assigned;
}

int CountAssigned(const std::array<int, sim::kNumHAnimJoints>& assigned) {
  return static_cast<int>(std::count_if(assigned.begin(), assigned.end(), [](int i) { return i >= 0; }));
}

std::vector<std::string> NamesOf(const std::vector<sim::Joint>& joints) {
  std::vector<std::string> names;
  names.reserve(joints.size());
  for (const sim::Joint& joint : joints) names.push_back(joint.name);
  return names;
}

}  // namespace

std::string_view FamilyName(SkeletonFamily family) {
  switch (family) {
    case SkeletonFamily::kUnknown: return "unknown";
    case SkeletonFamily::kHAnim: return "H-Anim";
    case SkeletonFamily::kCmuCgspeed: return "CMU BVH (cgspeed) / Mixamo without prefix";
    case SkeletonFamily::kPoserBvh: return "CMU BVH (Poser / Second Life)";
    case SkeletonFamily::kBiovisionBvh: return "CMU BVH (Biovision)";
    case SkeletonFamily::kMakeHumanDefault: return "MakeHuman default skeleton";
    case SkeletonFamily::kMakeHumanBvh: return "MakeHuman BVH rig";
    case SkeletonFamily::kCesiumMan: return "glTF CesiumMan";
    case SkeletonFamily::kDeepMimic: return "DeepMimic humanoid3d";
    case SkeletonFamily::kMixamo: return "Mixamo";
    case SkeletonFamily::kBlender: return "Blender metarig / Rigify";
    case SkeletonFamily::kUnreal: return "Unreal mannequin";
    case SkeletonFamily::kMaxBiped: return "3ds Max Biped";
    case SkeletonFamily::kVRoid: return "VRoid (VRM)";
    case SkeletonFamily::kDazGenesis: return "Daz Genesis 3/8";
    case SkeletonFamily::kCharacterCreator: return "Reallusion Character Creator";
  }
  return "unknown";
}

const std::vector<FamilyMapping>& MappingTable(SkeletonFamily family) {
  switch (family) {
    case SkeletonFamily::kCmuCgspeed:
    case SkeletonFamily::kMixamo: return kCmuCgspeedTable;
    case SkeletonFamily::kPoserBvh: return kPoserBvhTable;
    case SkeletonFamily::kBiovisionBvh: return kBiovisionBvhTable;
    case SkeletonFamily::kMakeHumanDefault: return kMakeHumanDefaultTable;
    case SkeletonFamily::kMakeHumanBvh: return kMakeHumanBvhTable;
    case SkeletonFamily::kCesiumMan: return kCesiumManTable;
    case SkeletonFamily::kDeepMimic: return kDeepMimicTable;
    case SkeletonFamily::kBlender: return kBlenderTable;
    case SkeletonFamily::kUnreal: return kUnrealTable;
    case SkeletonFamily::kMaxBiped: return kMaxBipedTable;
    case SkeletonFamily::kVRoid: return kVRoidTable;
    case SkeletonFamily::kDazGenesis: return kDazGenesisTable;
    case SkeletonFamily::kCharacterCreator: return kCharacterCreatorTable;
    case SkeletonFamily::kUnknown:
    case SkeletonFamily::kHAnim: return kEmptyTable;
  }
  return kEmptyTable;
}

std::optional<sim::HAnimJoint> LookUpJoint(SkeletonFamily family, std::string_view joint_name) {
  if (family == SkeletonFamily::kHAnim) return sim::ParseHAnimName(joint_name);
  const std::string_view name = TableName(family, joint_name);
  for (const FamilyMapping& row : MappingTable(family)) {
    for (std::string_view candidate : row.names) {
      if (EqualIgnoringCase(name, candidate)) return row.hanim;
    }
  }
  return std::nullopt;
}

SkeletonFamily DetectFamily(const std::vector<std::string>& joint_names) {
  SkeletonFamily best = SkeletonFamily::kUnknown;
  int best_count = kRetargetingMinimum - 1;
  for (SkeletonFamily family : kFamilies) {
    const int count = CountAssigned(Assign(family, joint_names));
    if (count > best_count) {
      best = family;
      best_count = count;
    }
  }
  return best;
}

int ApplyFamily(SkeletonFamily family, std::vector<sim::Joint>& joints) {
  for (sim::Joint& joint : joints) joint.hanim.reset();
  if (family == SkeletonFamily::kUnknown) return 0;
  const std::array<int, sim::kNumHAnimJoints> assigned = Assign(family, NamesOf(joints));
  for (int h = 0; h < sim::kNumHAnimJoints; ++h) {
    if (assigned[h] >= 0) joints[assigned[h]].hanim = static_cast<HAnimJoint>(h);
  }
  return CountAssigned(assigned);
}

SkeletonFamily MapToHAnim(std::vector<sim::Joint>& joints) {
  const SkeletonFamily family = DetectFamily(NamesOf(joints));
  ApplyFamily(family, joints);
  return family;
}

}  // namespace costume::assets
