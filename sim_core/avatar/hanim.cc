#include "sim_core/avatar/hanim.h"

#include <algorithm>
#include <cctype>
#include <string>

namespace costume::sim {
namespace {

struct HAnimEntry {
  HAnimJoint joint;
  std::string_view name;      // H-Anim 2.0
  std::string_view old_name;  // H-Anim 1.1, where it differs
  std::optional<HAnimJoint> parent;
  HAnimJoint mirror;
};

using J = HAnimJoint;
constexpr HAnimEntry kEntries[kNumHAnimJoints] = {
    {J::kHumanoidRoot, "humanoid_root", "HumanoidRoot", std::nullopt, J::kHumanoidRoot},
    {J::kSacroiliac, "sacroiliac", "", J::kHumanoidRoot, J::kSacroiliac},
    {J::kLHip, "l_hip", "", J::kSacroiliac, J::kRHip},
    {J::kLKnee, "l_knee", "", J::kLHip, J::kRKnee},
    {J::kLTalocrural, "l_talocrural", "l_ankle", J::kLKnee, J::kRTalocrural},
    {J::kRHip, "r_hip", "", J::kSacroiliac, J::kLHip},
    {J::kRKnee, "r_knee", "", J::kRHip, J::kLKnee},
    {J::kRTalocrural, "r_talocrural", "r_ankle", J::kRKnee, J::kLTalocrural},
    {J::kVl5, "vl5", "", J::kHumanoidRoot, J::kVl5},
    {J::kVc7, "vc7", "", J::kVl5, J::kVc7},
    {J::kSkullbase, "skullbase", "", J::kVc7, J::kSkullbase},
    {J::kLShoulder, "l_shoulder", "", J::kVc7, J::kRShoulder},
    {J::kLElbow, "l_elbow", "", J::kLShoulder, J::kRElbow},
    {J::kLRadiocarpal, "l_radiocarpal", "l_wrist", J::kLElbow, J::kRRadiocarpal},
    {J::kRShoulder, "r_shoulder", "", J::kVc7, J::kLShoulder},
    {J::kRElbow, "r_elbow", "", J::kRShoulder, J::kLElbow},
    {J::kRRadiocarpal, "r_radiocarpal", "r_wrist", J::kRElbow, J::kLRadiocarpal},
};

const HAnimEntry& EntryOf(HAnimJoint joint) { return kEntries[static_cast<int>(joint)]; }

bool EqualIgnoringCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

}  // namespace

std::string_view HAnimName(HAnimJoint joint) { return EntryOf(joint).name; }

std::optional<HAnimJoint> ParseHAnimName(std::string_view name) {
  for (const HAnimEntry& entry : kEntries) {
    if (EqualIgnoringCase(name, entry.name)) return entry.joint;
    if (!entry.old_name.empty() && EqualIgnoringCase(name, entry.old_name)) return entry.joint;
  }
  return std::nullopt;
}

std::optional<HAnimJoint> HAnimParent(HAnimJoint joint) { return EntryOf(joint).parent; }

HAnimJoint HAnimMirror(HAnimJoint joint) { return EntryOf(joint).mirror; }

const std::array<HAnimJoint, kNumHAnimJoints>& AllHAnimJoints() {
  static const std::array<HAnimJoint, kNumHAnimJoints> joints = [] {
    std::array<HAnimJoint, kNumHAnimJoints> all{};
    for (int i = 0; i < kNumHAnimJoints; ++i) all[i] = kEntries[i].joint;
    return all;
  }();
  return joints;
}

}  // namespace costume::sim
