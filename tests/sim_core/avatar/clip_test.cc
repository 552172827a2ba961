// Clip sampling (interpolation, wrap-around, hold) and retargeting between skeletons.
#include "sim_core/avatar/clip.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "sim_core/common/input_error.h"
#include "tests/support/refusal.h"

namespace costume::sim {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Quaterniond About(const Eigen::Vector3d& axis, double degrees) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * kPi / 180.0, axis.normalized()));
}

using test::RefusalOf;

// ---- sampling ---------------------------------------------------------------------------

std::shared_ptr<const Skeleton> OneJoint() {
  std::vector<Joint> joints(1);
  joints[0].name = "only";
  return Skeleton::Create("one", joints);
}

/// Three frames 0.5 s apart: 0°, 60°, 120° about z, root at x = 0, 1, 2.
Clip ThreeFrames(bool loops) {
  Clip clip;
  clip.name = "turn";
  clip.skeleton = OneJoint();
  clip.frame_time = 0.5;
  clip.loops = loops;
  for (int f = 0; f < 3; ++f) {
    Pose pose = RestPose(*clip.skeleton);
    pose.rotations[0] = About(Eigen::Vector3d::UnitZ(), 60.0 * f);
    pose.root_translation = {static_cast<double>(f), 0, 0};
    clip.frames.push_back(pose);
  }
  return clip;
}

double DegreesAboutZ(const Pose& pose) {
  const Eigen::AngleAxisd aa(pose.rotations[0]);
  return aa.angle() * aa.axis().z() * 180.0 / kPi;
}

TEST(SampleClip, InterpolatesBetweenNeighbouringFrames) {
  const Clip clip = ThreeFrames(true);
  Pose pose;
  SampleClip(clip, 0.25, pose);
  EXPECT_NEAR(DegreesAboutZ(pose), 30.0, 1e-9);
  EXPECT_NEAR(pose.root_translation.x(), 0.5, 1e-12);
  SampleClip(clip, 0.875, pose);
  EXPECT_NEAR(DegreesAboutZ(pose), 105.0, 1e-9);
}

TEST(SampleClip, LoopingClipWrapsFromLastFrameToFirstTravellingOn) {
  const Clip clip = ThreeFrames(true);
  EXPECT_DOUBLE_EQ(clip.duration(), 1.5);
  // The root walks 1 m a frame along x: 3 m a pass, the next pass starting where it ends.
  EXPECT_NEAR(LoopTravel(clip).x(), 3.0, 1e-12);
  Pose pose;
  // Halfway from the last frame (120°, x = 2) to the next pass's first (0°, x = 3).
  SampleClip(clip, 1.25, pose);
  EXPECT_NEAR(DegreesAboutZ(pose), 60.0, 1e-9);
  EXPECT_NEAR(pose.root_translation.x(), 2.5, 1e-12);
  SampleClip(clip, -0.25, pose);  // the pass before: from x = −1 to 0
  EXPECT_NEAR(DegreesAboutZ(pose), 60.0, 1e-9);
  EXPECT_NEAR(pose.root_translation.x(), -0.5, 1e-12);
  SampleClip(clip, 1.5 + 3.0 + 0.25, pose);  // three passes on: 0.5 m into the fourth
  EXPECT_NEAR(DegreesAboutZ(pose), 30.0, 1e-9);
  EXPECT_NEAR(pose.root_translation.x(), 9.5, 1e-12);
}

TEST(SampleClip, NonLoopingClipHoldsItsEnds) {
  const Clip clip = ThreeFrames(false);
  EXPECT_DOUBLE_EQ(clip.duration(), 1.0);
  Pose pose;
  SampleClip(clip, 1.25, pose);
  EXPECT_NEAR(DegreesAboutZ(pose), 120.0, 1e-9);
  EXPECT_NEAR(pose.root_translation.x(), 2.0, 1e-12);
  SampleClip(clip, 100.0, pose);
  EXPECT_NEAR(DegreesAboutZ(pose), 120.0, 1e-9);
  SampleClip(clip, -3.0, pose);
  EXPECT_NEAR(DegreesAboutZ(pose), 0.0, 1e-9);
}

TEST(ValidateClip, RefusalsNameTheClipAndField) {
  EXPECT_NO_THROW(ValidateClip(ThreeFrames(true)));
  auto expect = [](const Clip& clip, const std::string& word) {
    const std::string message = RefusalOf([&] { ValidateClip(clip); });
    EXPECT_NE(message.find("clip 'turn'"), std::string::npos) << message;
    EXPECT_NE(message.find(word), std::string::npos) << "'" << word << "' not in: " << message;
  };
  Clip clip = ThreeFrames(true);
  clip.skeleton.reset();
  expect(clip, "skeleton");
  clip = ThreeFrames(true);
  clip.frames.clear();
  expect(clip, "no frames");
  for (double bad : {0.0, -0.1, std::nan(""), 1e-300, 0.99e-4, 10.01, HUGE_VAL}) {
    clip = ThreeFrames(true);
    clip.frame_time = bad;
    expect(clip, "frame_time");
    expect(clip, "(allowed: [0.0001, 10])");
  }
  // The bounds themselves are kept: 10 kHz capture, and a slide show's ten seconds.
  for (double edge : {kMinFrameTime, kMaxFrameTime}) {
    clip = ThreeFrames(true);
    clip.frame_time = edge;
    EXPECT_NO_THROW(ValidateClip(clip)) << edge;
  }
  clip = ThreeFrames(true);
  clip.frames[1].rotations.push_back(Eigen::Quaterniond::Identity());
  expect(clip, "frame 1: 2 joint rotations, skeleton has 1");
  clip = ThreeFrames(true);
  clip.frames[2].rotations[0].coeffs().setZero();
  expect(clip, "frame 2");
  clip = ThreeFrames(true);
  clip.frames[0].root_translation.y() = std::nan("");
  expect(clip, "root translation");
  // A damaged BVH's root jumped 2.5e298 m for one frame: refused, as a stage is far smaller.
  clip = ThreeFrames(true);
  clip.frames[1].root_translation.x() = -2.5e298;
  expect(clip, "frame 1: root translation coordinate 2.5e+298 m (allowed: within ±10000 m");
  clip.frames[1].root_translation.x() = kMaxCoordinate;
  EXPECT_NO_THROW(ValidateClip(clip));
}

// ---- retargeting ------------------------------------------------------------------------

struct Variant {
  double arm_raise = 0.0;  // [deg] the arms' rest turned up by this much (70: T-pose)
  double scale = 1.0;
  double hip_half_width = 0.1;  // [m] each hip's distance from the body's midline
  double thigh = 0.45;          // [m] hip to knee
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  Eigen::Quaterniond turn = Eigen::Quaterniond::Identity();
};

/// A hand-built H-Anim humanoid (arms 20° from the body) with an unmapped fingertip joint
/// after each wrist, varied as `variant` says. Returns joint world frames by name too.
std::shared_ptr<const Skeleton> TestHumanoid(const Variant& variant = {}) {
  using J = HAnimJoint;
  std::map<J, Eigen::Vector3d> at = {
      {J::kHumanoidRoot, {0, 1, 0}},
      {J::kSacroiliac, {0, 1, 0}},
      {J::kLHip, {variant.hip_half_width, 0.95, 0}},
      {J::kLKnee, {variant.hip_half_width, 0.95 - variant.thigh, 0}},
      {J::kLTalocrural, {0.1, 0.08, 0}},
      {J::kVl5, {0, 1.1, 0}},
      {J::kVc7, {0, 1.45, 0}},       {J::kSkullbase, {0, 1.6, 0}}};
  const double a = 20.0 * kPi / 180.0;
  at[J::kLShoulder] = {0.2, 1.42, 0};
  at[J::kLElbow] = at[J::kLShoulder] + 0.3 * Eigen::Vector3d(std::sin(a), -std::cos(a), 0);
  at[J::kLRadiocarpal] = at[J::kLElbow] + 0.25 * Eigen::Vector3d(std::sin(a), -std::cos(a), 0);
  for (J left :
       {J::kLHip, J::kLKnee, J::kLTalocrural, J::kLShoulder, J::kLElbow, J::kLRadiocarpal}) {
    at[HAnimMirror(left)] = at[left].cwiseProduct(Eigen::Vector3d(-1, 1, 1));
  }
  std::vector<std::string> names;
  std::vector<int> parents;
  std::vector<Eigen::Isometry3d> world;
  auto add = [&](const std::string& name, int parent, const Eigen::Vector3d& position,
                 const Eigen::Matrix3d& rotation) {
    Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
    frame.linear() = rotation;
    frame.translation() = position;
    names.push_back(name);
    parents.push_back(parent);
    world.push_back(frame);
  };
  for (J joint : AllHAnimJoints()) {
    const std::optional<J> parent = HAnimParent(joint);
    Eigen::Vector3d position = at[joint];
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    // Raise each arm about the shoulder (about +z on the left, −z on the right).
    for (J shoulder : {J::kLShoulder, J::kRShoulder}) {
      const bool in_arm = joint == shoulder || HAnimParent(joint) == shoulder ||
                          (HAnimParent(joint) && HAnimParent(*HAnimParent(joint)) == shoulder);
      if (!in_arm) continue;
      const double sign = shoulder == J::kLShoulder ? 1.0 : -1.0;
      const Eigen::Matrix3d raise =
          About(Eigen::Vector3d::UnitZ(), sign * variant.arm_raise).toRotationMatrix();
      position = at[shoulder] + raise * (position - at[shoulder]);
      rotation = raise;
    }
    add(std::string(HAnimName(joint)), parent ? static_cast<int>(*parent) : -1, position, rotation);
  }
  for (J wrist : {J::kLRadiocarpal, J::kRRadiocarpal}) {
    const int index = static_cast<int>(wrist);
    const Eigen::Vector3d along =
        (world[index].translation() - world[static_cast<int>(*HAnimParent(wrist))].translation())
            .normalized();
    add(wrist == J::kLRadiocarpal ? "l_fingertip" : "r_fingertip", index,
        world[index].translation() + 0.15 * along, world[index].linear());
  }
  std::vector<Joint> joints(names.size());
  for (std::size_t j = 0; j < names.size(); ++j) {
    Eigen::Isometry3d placed = world[j];
    placed.translation() = variant.turn * (variant.scale * placed.translation()) + variant.shift;
    placed.linear() = variant.turn.toRotationMatrix() * placed.linear();
    world[j] = placed;
    joints[j].name = names[j];
    joints[j].parent = parents[j];
    joints[j].rest_local = parents[j] < 0 ? placed : world[parents[j]].inverse() * placed;
    if (j < static_cast<std::size_t>(kNumHAnimJoints)) joints[j].hanim = static_cast<J>(j);
  }
  return Skeleton::Create("test humanoid", joints);
}

Pose RandomPose(const Skeleton& skeleton, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Pose pose = RestPose(skeleton);
  for (Eigen::Quaterniond& q : pose.rotations) {
    q = About(Eigen::Vector3d(unit(random), unit(random), unit(random)), 60.0 * unit(random));
  }
  pose.root_translation = {0.1, -0.05, 0.3};
  pose.orientation = About(Eigen::Vector3d(0.2, 1.0, 0.1), 35.0);
  return pose;
}

std::vector<Eigen::Vector3d> Positions(const Skeleton& skeleton, const Pose& pose) {
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(skeleton, pose, world);
  std::vector<Eigen::Vector3d> positions;
  for (const Eigen::Isometry3d& frame : world) positions.push_back(frame.translation());
  return positions;
}

TEST(Retargeter, OntoItselfReproducesEveryJointPosition) {
  const auto skeleton = TestHumanoid();
  const Retargeter retargeter(skeleton, skeleton);
  for (unsigned seed : {1u, 2u, 3u}) {
    const Pose source = RandomPose(*skeleton, seed);
    Pose target;
    retargeter.Apply(source, target);
    const auto expected = Positions(*skeleton, source);
    const auto got = Positions(*skeleton, target);
    for (std::size_t j = 0; j < expected.size(); ++j) {
      EXPECT_LT((got[j] - expected[j]).norm(), 1e-9) << skeleton->joint(j).name;
    }
  }
}

TEST(Retargeter, TPoseTargetPointsItsArmsWhereTheSourceDoes) {
  const auto source = TestHumanoid();
  Variant t_pose;
  t_pose.arm_raise = 70.0;  // 20° + 70°: arms horizontal
  const auto target = TestHumanoid(t_pose);
  const Retargeter retargeter(source, target);
  Pose raised = RestPose(*source);
  auto set = [&](HAnimJoint joint, const Eigen::Quaterniond& q) {
    raised.rotations[source->Find(joint)] = q;
  };
  set(HAnimJoint::kLShoulder,
      About(Eigen::Vector3d::UnitZ(), 60) * About(Eigen::Vector3d::UnitX(), -30));
  set(HAnimJoint::kLElbow, About(Eigen::Vector3d::UnitX(), -40));
  set(HAnimJoint::kLRadiocarpal, About(Eigen::Vector3d::UnitZ(), 15));
  set(HAnimJoint::kRShoulder, About(Eigen::Vector3d::UnitZ(), -80));
  set(HAnimJoint::kRElbow, About(Eigen::Vector3d::UnitX(), -20));
  for (const Pose& source_pose : {RestPose(*source), raised}) {
    Pose target_pose;
    retargeter.Apply(source_pose, target_pose);
    const auto s = Positions(*source, source_pose);
    const auto t = Positions(*target, target_pose);
    for (const char* side : {"l_", "r_"}) {
      const std::string chain[] = {std::string(side) + "shoulder", std::string(side) + "elbow",
                                   std::string(side) + "radiocarpal",
                                   std::string(side) + "fingertip"};
      for (int k = 0; k + 1 < 4; ++k) {
        const int a = source->FindByName(chain[k]);
        const int b = source->FindByName(chain[k + 1]);
        const Eigen::Vector3d want = (s[b] - s[a]).normalized();
        const Eigen::Vector3d got = (t[b] - t[a]).normalized();
        EXPECT_LT((got - want).norm(), 1e-9) << chain[k] << " → " << chain[k + 1];
      }
    }
  }
}

TEST(Retargeter, ScaledTargetScalesRootTranslationByLegLength) {
  const auto source = TestHumanoid();
  Variant big;
  big.scale = 1.3;
  big.shift = {0.5, 0.0, -2.0};
  const auto target = TestHumanoid(big);
  const Retargeter retargeter(source, target);
  const Pose source_pose = RandomPose(*source, 7);
  Pose target_pose;
  retargeter.Apply(source_pose, target_pose);
  EXPECT_LT((target_pose.root_translation - 1.3 * source_pose.root_translation).norm(), 1e-12);
  const auto s = Positions(*source, source_pose);
  const auto t = Positions(*target, target_pose);
  for (std::size_t j = 1; j < s.size(); ++j) {
    EXPECT_LT(((t[j] - t[0]) - 1.3 * (s[j] - s[0])).norm(), 1e-9) << source->joint(j).name;
  }
}

TEST(Retargeter, TurnedTargetMovesInItsOwnFacing) {
  const auto source = TestHumanoid();
  Variant turned;
  turned.turn = About(Eigen::Vector3d::UnitY(), 90.0);  // faces +x instead of +z
  const auto target = TestHumanoid(turned);
  const Retargeter retargeter(source, target);
  Pose source_pose = RandomPose(*source, 11);
  source_pose.orientation.setIdentity();
  Pose target_pose;
  retargeter.Apply(source_pose, target_pose);
  EXPECT_LT((target_pose.root_translation - turned.turn * source_pose.root_translation).norm(),
            1e-12);
  const auto s = Positions(*source, source_pose);
  const auto t = Positions(*target, target_pose);
  for (std::size_t j = 1; j < s.size(); ++j) {
    EXPECT_LT(((t[j] - t[0]) - turned.turn * (s[j] - s[0])).norm(), 1e-9) << source->joint(j).name;
  }
}

TEST(Retargeter, RefusesSkeletonsWithoutTheLegsAndArms) {
  std::vector<Joint> joints(2);
  joints[0].name = "root";
  joints[0].hanim = HAnimJoint::kHumanoidRoot;
  joints[1].name = "l_hip";
  joints[1].parent = 0;
  joints[1].rest_local.translation() = Eigen::Vector3d(0.1, -0.1, 0);
  joints[1].hanim = HAnimJoint::kLHip;
  const auto stub = Skeleton::Create("stub", joints);
  const std::string message = RefusalOf([&] { Retargeter(TestHumanoid(), stub); });
  EXPECT_NE(message.find("stub"), std::string::npos) << message;
  EXPECT_NE(message.find("l_knee"), std::string::npos) << message;
  EXPECT_EQ(message.find("l_hip"), std::string::npos) << message;
}

// A damaged file can collapse the hips or a thigh to a point; the facing and the root's
// scale would then be 0/0, and the avatar would vanish into NaN or infinity when played.
TEST(Retargeter, RefusesAThighOfNoLength) {
  Variant collapsed;
  collapsed.thigh = 0.0;
  for (bool as_source : {true, false}) {
    const auto bad = TestHumanoid(collapsed);
    const std::string message = RefusalOf(
        [&] { as_source ? Retargeter(bad, TestHumanoid()) : Retargeter(TestHumanoid(), bad); });
    EXPECT_NE(message.find("l_hip to l_knee is 0 m"), std::string::npos) << message;
    EXPECT_NE(message.find("allowed: at least 0.001 m"), std::string::npos) << message;
  }
  collapsed.thigh = 0.002;  // a 2 mm thigh is odd but measurable: the root's travel × 225
  const Retargeter tiny(TestHumanoid(collapsed), TestHumanoid());
  const Pose source_pose = RandomPose(*TestHumanoid(collapsed), 3);
  Pose target_pose;
  tiny.Apply(source_pose, target_pose);
  EXPECT_LT((target_pose.root_translation - 225.0 * source_pose.root_translation).norm(), 1e-9);
}

TEST(Retargeter, RefusesHipsAtOnePoint) {
  Variant collapsed;
  collapsed.hip_half_width = 0.0;
  const std::string message =
      RefusalOf([&] { Retargeter(TestHumanoid(collapsed), TestHumanoid()); });
  EXPECT_NE(message.find("l_hip and r_hip are 0 m apart"), std::string::npos) << message;
  EXPECT_NE(message.find("allowed: at least 0.001 m"), std::string::npos) << message;
}

}  // namespace
}  // namespace costume::sim
