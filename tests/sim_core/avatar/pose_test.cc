// Forward kinematics against positions computed by hand.
#include "sim_core/avatar/pose.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <numbers>
#include <vector>

namespace costume::sim {
namespace {

constexpr double kHalfPi = std::numbers::pi / 2.0;

Eigen::Quaterniond About(const Eigen::Vector3d& axis, double angle) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis));
}

/// root at `root` → a 1 m along x → b 1 m along x (identity rest rotations unless given).
// GCC 12 at -O3 warns that assigning a one-letter literal to a std::string may overlap
// (-Wrestrict, a false positive: GCC bug 105329); giving the names as strings avoids it.
std::shared_ptr<const Skeleton> Chain(
    const Eigen::Vector3d& root, const Eigen::Quaterniond& a_rest = Eigen::Quaterniond::Identity(),
    const Eigen::Vector3d& b_offset = Eigen::Vector3d::UnitX()) {
  std::vector<Joint> joints(3);
  joints[0].name = std::string("root");
  joints[0].rest_local.translation() = root;
  joints[1].name = std::string("a");
  joints[1].parent = 0;
  joints[1].rest_local.translation() = Eigen::Vector3d::UnitX();
  joints[1].rest_local.linear() = a_rest.toRotationMatrix();
  joints[2].name = std::string("b");
  joints[2].parent = 1;
  joints[2].rest_local.translation() = b_offset;
  return Skeleton::Create("chain", joints);
}

void ExpectAt(const std::vector<Eigen::Isometry3d>& world, int joint,
              const Eigen::Vector3d& expected) {
  EXPECT_LT((world[joint].translation() - expected).norm(), 1e-12)
      << "joint " << joint << " at " << world[joint].translation().transpose() << ", expected "
      << expected.transpose();
}

TEST(ComputeJointWorld, RestPoseGivesRestWorld) {
  const auto skeleton = Chain({0, 1, 0});
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(*skeleton, RestPose(*skeleton), world);
  for (int j = 0; j < 3; ++j) EXPECT_TRUE(world[j].isApprox(skeleton->rest_world()[j], 1e-12));
}

TEST(ComputeJointWorld, MiddleJointTurnsOnlyItsChild) {
  // a turns 90° about z: b, 1 m along a's x, goes from (2, 0, 0) to (1, 1, 0).
  const auto skeleton = Chain(Eigen::Vector3d::Zero());
  Pose pose = RestPose(*skeleton);
  pose.rotations[1] = About(Eigen::Vector3d::UnitZ(), kHalfPi);
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(*skeleton, pose, world);
  ExpectAt(world, 0, {0, 0, 0});
  ExpectAt(world, 1, {1, 0, 0});
  ExpectAt(world, 2, {1, 1, 0});
}

TEST(ComputeJointWorld, RootTurnsTheWholeChain) {
  const auto skeleton = Chain(Eigen::Vector3d::Zero());
  Pose pose = RestPose(*skeleton);
  pose.rotations[0] = About(Eigen::Vector3d::UnitZ(), kHalfPi);
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(*skeleton, pose, world);
  ExpectAt(world, 1, {0, 1, 0});
  ExpectAt(world, 2, {0, 2, 0});
}

TEST(ComputeJointWorld, RotationIsInTheJointsRestFrame) {
  // a's rest frame is turned 90° about z; a's pose turns it 90° about its own x. b is 1 m
  // along a's y: Rz90·Rx90·y = Rz90·z = z, so b is at (1, 0, 1). (Applied in world axes
  // instead, Rx90·Rz90·y = Rx90·(−x) = −x would put b at (0, 0, 0).)
  const auto skeleton = Chain(Eigen::Vector3d::Zero(), About(Eigen::Vector3d::UnitZ(), kHalfPi),
                              Eigen::Vector3d::UnitY());
  Pose pose = RestPose(*skeleton);
  pose.rotations[1] = About(Eigen::Vector3d::UnitX(), kHalfPi);
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(*skeleton, pose, world);
  ExpectAt(world, 2, {1, 0, 1});
}

TEST(ComputeJointWorld, TranslationThenOrientationAboutTheOrigin) {
  // Root rest (0, 1, 0) moved by (0, 0, 2), then the avatar turned 90° about y (z → x):
  // Ry90·(0, 1, 2) = (2, 1, 0); a at Ry90·(1, 1, 2) = (2, 1, −1); b at Ry90·(2, 1, 2) = (2, 1, −2).
  const auto skeleton = Chain({0, 1, 0});
  Pose pose = RestPose(*skeleton);
  pose.root_translation = {0, 0, 2};
  pose.orientation = About(Eigen::Vector3d::UnitY(), kHalfPi);
  std::vector<Eigen::Isometry3d> world;
  ComputeJointWorld(*skeleton, pose, world);
  ExpectAt(world, 0, {2, 1, 0});
  ExpectAt(world, 1, {2, 1, -1});
  ExpectAt(world, 2, {2, 1, -2});
}

TEST(InterpolatePoses, HalfwayIsHalfTheAngleAndTheMeanTranslation) {
  const auto skeleton = Chain(Eigen::Vector3d::Zero());
  Pose a = RestPose(*skeleton);
  Pose b = RestPose(*skeleton);
  b.rotations[1] = About(Eigen::Vector3d::UnitZ(), kHalfPi);
  b.root_translation = {0, 2, 4};
  Pose mid;
  InterpolatePoses(a, b, 0.5, mid);
  EXPECT_NEAR(mid.rotations[1].angularDistance(About(Eigen::Vector3d::UnitZ(), kHalfPi / 2)), 0.0,
              1e-12);
  EXPECT_TRUE(mid.root_translation.isApprox(Eigen::Vector3d(0, 1, 2), 1e-12));
}

// Closed forms: a quarter turn about z takes x to y, about x takes y to z; with x then y
// applied in that order (intrinsic: about x, then about the turned y), y goes to z and z to x.
// Applied the other way round, y would go to x.
TEST(PostureRotation, TurnsAboutTheRestAxesInTheOrderXYZ) {
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ();
  const auto near = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return (a - b).norm() < 1e-12;
  };
  EXPECT_TRUE(near(PostureRotation({0, 0, 90}) * x, y));
  EXPECT_TRUE(near(PostureRotation({90, 0, 0}) * y, z));
  const Eigen::Quaterniond xy = PostureRotation({90, 90, 0});
  EXPECT_TRUE(near(xy * y, z));
  EXPECT_TRUE(near(xy * z, x));
  EXPECT_TRUE(near(PostureRotation({0, 360, 0}) * x, x));
}

// PostureDegrees undoes PostureRotation: angles within its ranges come back as they were,
// and any rotation, the gimbal's included, is rebuilt from the angles it gives.
TEST(PostureDegrees, GivesTheAnglesPostureRotationTurnsBy) {
  for (const Eigen::Vector3d& degrees :
       {Eigen::Vector3d(0, 0, -60), Eigen::Vector3d(45, 0, 0), Eigen::Vector3d(-30, 20, 170),
        Eigen::Vector3d(179, -89, -179), Eigen::Vector3d(0, 0, 0)}) {
    EXPECT_LT((PostureDegrees(PostureRotation(degrees)) - degrees).norm(), 1e-9)
        << degrees.transpose();
  }
  for (const Eigen::Vector3d& degrees :
       {Eigen::Vector3d(30, 90, 40), Eigen::Vector3d(30, -90, 40), Eigen::Vector3d(200, 100, 0),
        Eigen::Vector3d(-250, 15, 300)}) {
    const Eigen::Quaterniond q = PostureRotation(degrees);
    const Eigen::Vector3d back = PostureDegrees(q);
    EXPECT_LT(PostureRotation(back).angularDistance(q), 1e-9) << degrees.transpose();
    EXPECT_LE(std::abs(back.y()), 90.0 + 1e-9);
    EXPECT_LE(back.cwiseAbs().maxCoeff(), 180.0 + 1e-9);
  }
}

}  // namespace
}  // namespace costume::sim
