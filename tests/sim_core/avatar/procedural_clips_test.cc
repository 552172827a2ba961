// The built-in clips loop without a jump, move with realistic amplitudes and keep the
// built-in humanoid's feet out of the ground.
#include "sim_core/avatar/procedural_clips.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

using J = HAnimJoint;
constexpr double kDegrees = 180.0 / std::numbers::pi;

const std::shared_ptr<const Avatar>& Humanoid() {
  static const std::shared_ptr<const Avatar> avatar = MakeHumanoid();
  return avatar;
}

/// The largest joint rotation between two poses [rad].
double AngularStep(const Pose& a, const Pose& b) {
  double step = 0.0;
  for (std::size_t j = 0; j < a.rotations.size(); ++j) {
    step = std::max(step, a.rotations[j].angularDistance(b.rotations[j]));
  }
  return step;
}

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

std::vector<Eigen::Vector3d> JointPositions(const Skeleton& skeleton, const Pose& pose) {
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(skeleton, pose, world);
  std::vector<Eigen::Vector3d> positions;
  for (const auto& frame : world) positions.push_back(frame.translation());
  return positions;
}

/// The angle of the bone from `from` to `to` in the sagittal plane, from straight down,
/// positive forward (+z) [deg].
double SagittalAngle(const Skeleton& skeleton, const Pose& pose, J from, J to) {
  const auto p = JointPositions(skeleton, pose);
  const Eigen::Vector3d bone = p[skeleton.Find(to)] - p[skeleton.Find(from)];
  return std::atan2(bone.z(), -bone.y()) * kDegrees;
}

TEST(BuiltInClipNames, ListsTheSixClips) {
  EXPECT_EQ(BuiltInClipNames(),
            (std::vector<std::string>{"stand", "walk", "run", "jump", "kick", "dance"}));
}

TEST(MakeBuiltInClip, UnknownNameListsTheValidOnes) {
  try {
    MakeBuiltInClip("moonwalk", Humanoid()->shared_skeleton());
    FAIL() << "accepted";
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("moonwalk"), std::string::npos) << message;
    for (const std::string& name : BuiltInClipNames()) {
      EXPECT_NE(message.find(name), std::string::npos) << message;
    }
  }
  EXPECT_THROW(MakeBuiltInClip("walk", nullptr), InputError);
}

TEST(MakeBuiltInClip, EveryClipIsValidSixtyFramesPerSecondAndLoops) {
  for (const std::string& name : BuiltInClipNames()) {
    const Clip clip = MakeBuiltInClip(name, Humanoid()->shared_skeleton());
    EXPECT_NO_THROW(ValidateClip(clip)) << name;
    EXPECT_EQ(clip.name, name);
    EXPECT_DOUBLE_EQ(clip.frame_time, 1.0 / 60.0);
    EXPECT_TRUE(clip.loops);
    EXPECT_EQ(clip.category, name == "dance" ? ClipCategory::kChoreography : ClipCategory::kBasic);
    EXPECT_GE(clip.duration(), 0.5) << name;
  }
}

TEST(MakeBuiltInClip, LastFrameLeadsIntoTheFirstLikeAnyOtherStep) {
  for (const std::string& name : BuiltInClipNames()) {
    const Clip clip = MakeBuiltInClip(name, Humanoid()->shared_skeleton());
    const int n = static_cast<int>(clip.frames.size());
    std::vector<double> steps;
    std::vector<double> moves;
    for (int f = 0; f + 1 < n; ++f) {
      steps.push_back(AngularStep(clip.frames[f], clip.frames[f + 1]));
      moves.push_back(
          (clip.frames[f + 1].root_translation - clip.frames[f].root_translation).norm());
    }
    const double wrap = AngularStep(clip.frames[n - 1], clip.frames[0]);
    const double wrap_move =
        (clip.frames[0].root_translation - clip.frames[n - 1].root_translation).norm();
    // A loop closed one frame late or early (or not at all) steps far more than a frame.
    EXPECT_LE(wrap, 2.0 * Median(steps) + 0.2 / kDegrees)
        << name << ": median step " << Median(steps) * kDegrees << "°";
    EXPECT_LE(wrap_move, 2.0 * Median(moves) + 1e-3) << name;
    if (name != "jump" && name != "kick") {
      // These never come to rest, so a repeated frame at the seam (a stutter) shows too.
      EXPECT_GE(wrap, 0.5 * Median(steps)) << name;
    }
    EXPECT_GT(*std::max_element(steps.begin(), steps.end()), 0.0) << name << " does not move";
  }
}

TEST(MakeBuiltInClip, WalkSwingsHipsTwentyFiveDegreesAndArmsAgainstLegs) {
  const auto skeleton = Humanoid()->shared_skeleton();
  const Clip walk = MakeBuiltInClip("walk", skeleton);
  EXPECT_NEAR(walk.duration(), 1.1, 0.1);
  double hip_min = 1e9, hip_max = -1e9, knee_min = 1e9, knee_max = -1e9;
  double correlation = 0.0;
  for (const Pose& pose : walk.frames) {
    const double thigh = SagittalAngle(*skeleton, pose, J::kLHip, J::kLKnee);
    const double calf = SagittalAngle(*skeleton, pose, J::kLKnee, J::kLTalocrural);
    const double arm = SagittalAngle(*skeleton, pose, J::kLShoulder, J::kLElbow);
    const double pelvis_turn = 0.0;  // thigh angle is measured in the world; pelvis yaw is small
    hip_min = std::min(hip_min, thigh - pelvis_turn);
    hip_max = std::max(hip_max, thigh - pelvis_turn);
    knee_min = std::min(knee_min, thigh - calf);
    knee_max = std::max(knee_max, thigh - calf);
    correlation += thigh * arm;
  }
  EXPECT_NEAR(0.5 * (hip_max - hip_min), 25.0, 5.0);
  EXPECT_NEAR(knee_min, 0.0, 5.0);
  EXPECT_NEAR(knee_max, 60.0, 8.0);
  EXPECT_LT(correlation, 0.0) << "the left arm swings with the left leg";
}

TEST(MakeBuiltInClip, RunIsFasterAndLargerThanWalk) {
  const auto skeleton = Humanoid()->shared_skeleton();
  const Clip walk = MakeBuiltInClip("walk", skeleton);
  const Clip run = MakeBuiltInClip("run", skeleton);
  EXPECT_LT(run.duration(), walk.duration());
  auto range = [&](const Clip& clip) {
    double lo = 1e9, hi = -1e9;
    for (const Pose& pose : clip.frames) {
      const double thigh = SagittalAngle(*skeleton, pose, J::kLHip, J::kLKnee);
      lo = std::min(lo, thigh);
      hi = std::max(hi, thigh);
    }
    return hi - lo;
  };
  EXPECT_GT(range(run), range(walk) + 10.0);
}

TEST(MakeBuiltInClip, JumpRisesAboutThirtyCentimetres) {
  const Clip jump = MakeBuiltInClip("jump", Humanoid()->shared_skeleton());
  double top = -1e9, bottom = 1e9;
  for (const Pose& pose : jump.frames) {
    top = std::max(top, pose.root_translation.y());
    bottom = std::min(bottom, pose.root_translation.y());
  }
  EXPECT_NEAR(top, 0.3, 0.07);
  EXPECT_LT(bottom, -0.1) << "no crouch";
}

TEST(MakeBuiltInClip, KickRaisesOneThighToAboutSeventyDegrees) {
  const auto skeleton = Humanoid()->shared_skeleton();
  const Clip kick = MakeBuiltInClip("kick", skeleton);
  double left = -1e9, right = -1e9;
  for (const Pose& pose : kick.frames) {
    left = std::max(left, SagittalAngle(*skeleton, pose, J::kLHip, J::kLKnee));
    right = std::max(right, SagittalAngle(*skeleton, pose, J::kRHip, J::kRKnee));
  }
  EXPECT_NEAR(std::max(left, right), 70.0, 10.0);
  EXPECT_LT(std::min(left, right), 25.0) << "both legs kick";
}

TEST(MakeBuiltInClip, DanceMovesArmsAndHipsThroughSeveralSeconds) {
  const auto skeleton = Humanoid()->shared_skeleton();
  const Clip dance = MakeBuiltInClip("dance", skeleton);
  EXPECT_GE(dance.duration(), 3.0);
  double hand_lo = 1e9, hand_hi = -1e9, hip_lo = 1e9, hip_hi = -1e9;
  for (const Pose& pose : dance.frames) {
    const auto p = JointPositions(*skeleton, pose);
    hand_lo = std::min(hand_lo, p[skeleton->Find(J::kLRadiocarpal)].y());
    hand_hi = std::max(hand_hi, p[skeleton->Find(J::kLRadiocarpal)].y());
    hip_lo = std::min(hip_lo, p[skeleton->Find(J::kSacroiliac)].x());
    hip_hi = std::max(hip_hi, p[skeleton->Find(J::kSacroiliac)].x());
  }
  EXPECT_GT(hand_hi - hand_lo, 0.5) << "the arms hardly move";
  EXPECT_GT(hip_hi - hip_lo, 0.04) << "the hips hardly sway";
}

/// The lowest skinned vertex of the humanoid over all frames of `name`, and the highest
/// of the per-frame lowest ones [m].
std::pair<double, double> FootClearance(const std::string& name) {
  const Avatar& avatar = *Humanoid();
  const Clip clip = MakeBuiltInClip(name, avatar.shared_skeleton());
  std::vector<Eigen::Isometry3d> world;
  std::vector<Eigen::Isometry3d> skinning;
  Points vertices;
  double lowest = 1e9;
  double highest_lowest = -1e9;
  for (const Pose& pose : clip.frames) {
    ComputeJointWorld(avatar.skeleton(), pose, world);
    SkinVertices(avatar, world, skinning, vertices);
    lowest = std::min(lowest, vertices.col(1).minCoeff());
    highest_lowest = std::max(highest_lowest, vertices.col(1).minCoeff());
  }
  return {lowest, highest_lowest};
}

TEST(MakeBuiltInClip, FeetStayOutOfTheGround) {
  for (const std::string& name : BuiltInClipNames()) {
    const auto [lowest, highest_lowest] = FootClearance(name);
    EXPECT_GE(lowest, -0.02) << name;
    if (name == "walk" || name == "stand" || name == "dance") {
      // Always one foot on the ground: the feet do not float either.
      EXPECT_LE(highest_lowest, 0.02) << name;
    }
  }
}

}  // namespace
}  // namespace costume::sim
