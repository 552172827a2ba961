// Skeleton::Create refuses malformed hierarchies; rest_world composes parent then child.
#include "sim_core/avatar/skeleton.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "sim_core/avatar/hanim.h"
#include "sim_core/common/input_error.h"
#include "tests/support/refusal.h"

namespace costume::sim {
namespace {

constexpr double kHalfPi = std::numbers::pi / 2.0;

using test::RefusalOf;

Joint MakeJoint(std::string name, int parent, Eigen::Vector3d translation,
                std::optional<HAnimJoint> hanim = std::nullopt) {
  Joint joint;
  joint.name = std::move(name);
  joint.parent = parent;
  joint.rest_local.translation() = translation;
  joint.hanim = hanim;
  return joint;
}

std::vector<Joint> Chain() {
  return {MakeJoint("root", -1, {0, 1, 0}, HAnimJoint::kHumanoidRoot),
          MakeJoint("hip", 0, {0.1, -0.1, 0}, HAnimJoint::kLHip),
          MakeJoint("knee", 1, {0, -0.4, 0})};
}

TEST(SkeletonCreate, RefusesNoJoints) {
  const std::string message = RefusalOf([] { Skeleton::Create("rig", {}); });
  EXPECT_NE(message.find("rig"), std::string::npos) << message;
  EXPECT_NE(message.find("no joints"), std::string::npos) << message;
}

TEST(SkeletonCreate, RefusesEmptyAndRepeatedNames) {
  std::vector<Joint> joints = Chain();
  joints[2].name = "hip";
  std::string message = RefusalOf([&] { Skeleton::Create("rig", joints); });
  EXPECT_NE(message.find("joint 2"), std::string::npos) << message;
  EXPECT_NE(message.find("'hip'"), std::string::npos) << message;
  EXPECT_NE(message.find("twice"), std::string::npos) << message;
  joints[2].name = "";
  message = RefusalOf([&] { Skeleton::Create("rig", joints); });
  EXPECT_NE(message.find("empty name"), std::string::npos) << message;
}

TEST(SkeletonCreate, RefusesParentNotBeforeChild) {
  for (int bad_parent : {2, 3, -2}) {
    std::vector<Joint> joints = Chain();
    joints[2].parent = bad_parent;
    const std::string message = RefusalOf([&] { Skeleton::Create("rig", joints); });
    EXPECT_NE(message.find("'knee'"), std::string::npos) << message;
    EXPECT_NE(message.find("parent index " + std::to_string(bad_parent)), std::string::npos)
        << message;
    EXPECT_NE(message.find("0..1"), std::string::npos) << message;
  }
}

TEST(SkeletonCreate, RefusesNonRigidOrNonFiniteRestTransforms) {
  std::vector<Eigen::Matrix3d> bad_linear;
  bad_linear.push_back(2.0 * Eigen::Matrix3d::Identity());             // scale
  bad_linear.push_back(Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal());  // mirror
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = 0.3;
  bad_linear.push_back(shear);
  for (const Eigen::Matrix3d& linear : bad_linear) {
    std::vector<Joint> joints = Chain();
    joints[1].rest_local.linear() = linear;
    const std::string message = RefusalOf([&] { Skeleton::Create("rig", joints); });
    EXPECT_NE(message.find("'hip'"), std::string::npos) << message;
    EXPECT_NE(message.find("not a rotation"), std::string::npos) << message;
  }
  std::vector<Joint> joints = Chain();
  joints[1].rest_local.translation().x() = std::nan("");
  const std::string message = RefusalOf([&] { Skeleton::Create("rig", joints); });
  EXPECT_NE(message.find("non-finite"), std::string::npos) << message;
}

TEST(SkeletonCreate, RefusesAnOffsetBeyondAnyStageButKeepsOneAtTheLimit) {
  std::vector<Joint> joints = Chain();
  joints[1].rest_local.translation() = Eigen::Vector3d(0.0, -kMaxCoordinate, 0.0);
  EXPECT_NO_THROW(Skeleton::Create("rig", joints));
  // Finite, and its square overflows: the coordinate is reported, not an infinite norm.
  joints[1].rest_local.translation() = Eigen::Vector3d(0.0, -2.5e298, 1e298);
  const std::string message = RefusalOf([&] { Skeleton::Create("rig", joints); });
  EXPECT_NE(message.find("'hip'): rest offset coordinate 2.5e+298 m (allowed: within ±10000 m"),
            std::string::npos)
      << message;
}

TEST(SkeletonCreate, AcceptsRotationsAndRefusesHAnimUsedTwice) {
  std::vector<Joint> joints = Chain();
  joints[1].rest_local.linear() =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  EXPECT_NO_THROW(Skeleton::Create("rig", joints));
  joints[2].hanim = HAnimJoint::kLHip;
  const std::string message = RefusalOf([&] { Skeleton::Create("rig", joints); });
  EXPECT_NE(message.find("l_hip"), std::string::npos) << message;
  EXPECT_NE(message.find("twice"), std::string::npos) << message;
}

TEST(Skeleton, RestWorldComposesParentThenChild) {
  // Root: 90° about z at (1, 0, 0). Child: 90° about x, 1 m along the root's x.
  // Grandchild: 1 m along the child's y. By hand: Rz90·x = y, so the child sits at
  // (1, 1, 0); Rz90·Rx90·y = Rz90·z = z, so the grandchild sits at (1, 1, 1).
  std::vector<Joint> joints = {MakeJoint("a", -1, {1, 0, 0}), MakeJoint("b", 0, {1, 0, 0}),
                               MakeJoint("c", 1, {0, 1, 0})};
  joints[0].rest_local.linear() =
      Eigen::AngleAxisd(kHalfPi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  joints[1].rest_local.linear() =
      Eigen::AngleAxisd(kHalfPi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const auto skeleton = Skeleton::Create("rig", joints);
  const auto& world = skeleton->rest_world();
  EXPECT_TRUE(world[0].translation().isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_TRUE(world[1].translation().isApprox(Eigen::Vector3d(1, 1, 0), 1e-12));
  EXPECT_TRUE(world[2].translation().isApprox(Eigen::Vector3d(1, 1, 1), 1e-12));
  // The grandchild's x axis: Rz90·Rx90·x = Rz90·x = y.
  EXPECT_TRUE(
      (world[2].linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(Skeleton, FindsJointsByNameAndHAnim) {
  const auto skeleton = Skeleton::Create("rig", Chain());
  EXPECT_EQ(skeleton->FindByName("knee"), 2);
  EXPECT_EQ(skeleton->FindByName("Knee"), -1);
  EXPECT_EQ(skeleton->Find(HAnimJoint::kLHip), 1);
  EXPECT_EQ(skeleton->Find(HAnimJoint::kRHip), -1);
  // The knee is not mapped: its vertices belong to the nearest mapped ancestor's segment.
  EXPECT_EQ(skeleton->HAnimSegmentOf(2), HAnimJoint::kLHip);
}

// A rig whose deform bones hang from helper bones under an unmapped root, as Rigify's DEF
// bones hang from its ORG and MCH bones: a chest bone with no mapped ancestor belongs to the
// bone it lies on (humanoid_root to vc7, from H-Anim's own hierarchy), not to nothing, and a
// twist bone on the upper arm to the shoulder's segment.
TEST(Skeleton, AJointWithNoMappedAncestorBelongsToTheBoneItLiesOn) {
  const auto mapped = [](Joint joint, HAnimJoint hanim) {
    joint.hanim = hanim;
    return joint;
  };
  std::vector<Joint> joints = {
      MakeJoint("root", -1, {0, 0, 0}),
      mapped(MakeJoint("DEF-hips", 0, {0, 1.0, 0}), HAnimJoint::kHumanoidRoot),
      MakeJoint("ORG-chest", 0, {0, 1.3, 0}),
      MakeJoint("DEF-chest", 2, {0, 0, 0}),
      mapped(MakeJoint("DEF-neck", 0, {0, 1.6, 0}), HAnimJoint::kVc7),
      mapped(MakeJoint("DEF-upper_arm.L", 0, {0.2, 1.5, 0}), HAnimJoint::kLShoulder),
      mapped(MakeJoint("DEF-forearm.L", 0, {0.3, 1.2, 0}), HAnimJoint::kLElbow),
      MakeJoint("DEF-upper_arm.L.001", 0, {0.25, 1.35, 0})};  // halfway down the upper arm
  const auto skeleton = Skeleton::Create("rigify-like", joints);
  EXPECT_EQ(skeleton->HAnimSegmentOf(3), HAnimJoint::kHumanoidRoot);  // on the root–vc7 bone
  EXPECT_EQ(skeleton->HAnimSegmentOf(7), HAnimJoint::kLShoulder);
  EXPECT_EQ(skeleton->HAnimSegmentOf(1), HAnimJoint::kHumanoidRoot);  // mapped: itself
}

TEST(ParseHAnimName, AcceptsOldAndNewNamesIgnoringCase) {
  EXPECT_EQ(ParseHAnimName("l_ankle"), HAnimJoint::kLTalocrural);
  EXPECT_EQ(ParseHAnimName("l_talocrural"), HAnimJoint::kLTalocrural);
  EXPECT_EQ(ParseHAnimName("HumanoidRoot"), HAnimJoint::kHumanoidRoot);
  EXPECT_EQ(ParseHAnimName("humanoid_root"), HAnimJoint::kHumanoidRoot);
  EXPECT_EQ(ParseHAnimName("L_KNEE"), HAnimJoint::kLKnee);
  EXPECT_EQ(ParseHAnimName("r_wrist"), HAnimJoint::kRRadiocarpal);
  for (const char* name : {"", "knee", "left_knee", "l_knee ", "l-knee", "l_kneecap", "root"}) {
    EXPECT_EQ(ParseHAnimName(name), std::nullopt) << name;
  }
}

TEST(HAnim, ParentsComeBeforeChildrenAndMirrorsPair) {
  const auto& all = AllHAnimJoints();
  for (int i = 0; i < kNumHAnimJoints; ++i) {
    const std::optional<HAnimJoint> parent = HAnimParent(all[i]);
    if (parent) {
      EXPECT_LT(static_cast<int>(*parent), i);
    }
    EXPECT_EQ(HAnimMirror(HAnimMirror(all[i])), all[i]);
    EXPECT_EQ(ParseHAnimName(HAnimName(all[i])), all[i]);
  }
}

}  // namespace
}  // namespace costume::sim
