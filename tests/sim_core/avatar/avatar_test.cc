// Linear blend skinning against rigid motions computed by hand; Create's refusals.
#include "sim_core/avatar/avatar.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "sim_core/common/input_error.h"
#include "tests/support/refusal.h"

namespace costume::sim {
namespace {

constexpr double kHalfPi = std::numbers::pi / 2.0;

using test::RefusalOf;

/// Root at the origin, "elbow" 1 m above it.
std::shared_ptr<const Skeleton> TwoJoints() {
  std::vector<Joint> joints(2);
  joints[0].name = "root";
  joints[0].hanim = HAnimJoint::kHumanoidRoot;
  joints[1].name = "elbow";
  joints[1].parent = 0;
  joints[1].rest_local.translation() = Eigen::Vector3d::UnitY();
  joints[1].hanim = HAnimJoint::kLElbow;
  return Skeleton::Create("two", joints);
}

/// Vertex 0 at (1, 1, 0) bound to the elbow only; vertex 1 at the same place, half to the
/// root and half to the elbow; vertex 2 at (0, 0, 1) bound to the root; one triangle.
AvatarData ThreeVertices() {
  AvatarData data;
  data.name = "test body";
  data.skeleton = TwoJoints();
  data.rest_vertices.resize(3, 3);
  data.rest_vertices << 1, 1, 0, 1, 1, 0, 0, 0, 1;
  data.triangles = {{0, 1, 2}};
  data.influence_joints.resize(3, kMaxInfluences);
  data.influence_weights.resize(3, kMaxInfluences);
  data.influence_joints.setConstant(-1);
  data.influence_weights.setZero();
  data.influence_joints(0, 0) = 1;
  data.influence_weights(0, 0) = 1.0;
  data.influence_joints(1, 0) = 0;
  data.influence_joints(1, 1) = 1;
  data.influence_weights(1, 0) = 0.5;
  data.influence_weights(1, 1) = 0.5;
  data.influence_joints(2, 0) = 0;
  data.influence_weights(2, 0) = 1.0;
  return data;
}

Points Skin(const Avatar& avatar, const Pose& pose) {
  std::vector<Eigen::Isometry3d> world;
  std::vector<Eigen::Isometry3d> skinning;
  Points vertices;
  ComputeJointWorld(avatar.skeleton(), pose, world);
  SkinVertices(avatar, world, skinning, vertices);
  return vertices;
}

TEST(SkinVertices, RestPoseReproducesRestVertices) {
  const auto avatar = Avatar::Create(ThreeVertices());
  const Points skinned = Skin(*avatar, RestPose(avatar->skeleton()));
  EXPECT_LT((skinned - avatar->rest_vertices()).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(SkinVertices, FullyBoundVertexMovesRigidlyAndBlendIsTheAverage) {
  const auto avatar = Avatar::Create(ThreeVertices());
  Pose pose = RestPose(avatar->skeleton());
  // The elbow turns 90° about z: (1, 1, 0) is (1, 0, 0) from the elbow, turned to (0, 1, 0),
  // so it goes to (0, 2, 0). Half bound: the mean of (1, 1, 0) and (0, 2, 0).
  pose.rotations[1] = Eigen::AngleAxisd(kHalfPi, Eigen::Vector3d::UnitZ());
  Points skinned = Skin(*avatar, pose);
  EXPECT_LT((skinned.row(0) - Eigen::RowVector3d(0, 2, 0)).norm(), 1e-12);
  EXPECT_LT((skinned.row(1) - Eigen::RowVector3d(0.5, 1.5, 0)).norm(), 1e-12);
  EXPECT_LT((skinned.row(2) - Eigen::RowVector3d(0, 0, 1)).norm(), 1e-12);
  // Moving the root carries everything along.
  pose.root_translation = {0, 0, 3};
  skinned = Skin(*avatar, pose);
  EXPECT_LT((skinned.row(0) - Eigen::RowVector3d(0, 2, 3)).norm(), 1e-12);
  EXPECT_LT((skinned.row(2) - Eigen::RowVector3d(0, 0, 4)).norm(), 1e-12);
}

TEST(Avatar, SegmentOfEachVertexIsItsHeaviestJoints) {
  const auto avatar = Avatar::Create(ThreeVertices());
  EXPECT_EQ(avatar->vertex_segments()[0], HAnimJoint::kLElbow);
  EXPECT_EQ(avatar->vertex_segments()[2], HAnimJoint::kHumanoidRoot);
}

void ExpectRefused(AvatarData data, const std::vector<std::string>& words) {
  const std::string message = RefusalOf([&] { Avatar::Create(std::move(data)); });
  ASSERT_FALSE(message.empty()) << "accepted";
  EXPECT_NE(message.find("test body"), std::string::npos) << message;
  for (const std::string& word : words) {
    EXPECT_NE(message.find(word), std::string::npos) << "'" << word << "' not in: " << message;
  }
}

TEST(AvatarCreate, RefusalsNameTheField) {
  AvatarData data = ThreeVertices();
  data.skeleton.reset();
  ExpectRefused(data, {"skeleton"});

  data = ThreeVertices();
  data.rest_vertices.resize(0, 3);
  ExpectRefused(data, {"rest_vertices"});

  data = ThreeVertices();
  data.rest_vertices(2, 1) = std::nan("");
  ExpectRefused(data, {"rest_vertices", "row 2"});

  data = ThreeVertices();
  data.rest_vertices(1, 2) = 1e308;
  ExpectRefused(data, {"rest_vertices row 1 has coordinate 1e+308 m", "±10000 m"});

  data = ThreeVertices();
  data.triangles.push_back({0, 1, 3});
  ExpectRefused(data, {"triangles[1]", "0..2"});

  data = ThreeVertices();
  data.influence_joints(2, 0) = 2;
  ExpectRefused(data, {"influence_joints", "vertex 2", "-1..1"});

  data = ThreeVertices();
  data.influence_weights(1, 0) = -0.5;
  data.influence_weights(1, 1) = 1.5;
  ExpectRefused(data, {"influence_weights", "vertex 1", ">= 0"});

  data = ThreeVertices();
  data.influence_weights(1, 1) = 0.4;
  ExpectRefused(data, {"influence_weights", "vertex 1", "sum", "0.9"});

  data = ThreeVertices();
  data.influence_weights.resize(2, kMaxInfluences);
  ExpectRefused(data, {"influence_weights", "rest_vertices"});
}

}  // namespace
}  // namespace costume::sim
