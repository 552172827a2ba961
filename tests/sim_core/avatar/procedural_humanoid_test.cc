// The built-in humanoid: a complete H-Anim skeleton of the measured height, a surface of
// closed outward segment meshes, and skin weights that bend rigidly away from the joints.
#include "sim_core/avatar/procedural_humanoid.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <set>
#include <utility>
#include <vector>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

using J = HAnimJoint;

Eigen::Vector3d RestAt(const Skeleton& skeleton, J joint) {
  return skeleton.rest_world()[skeleton.Find(joint)].translation();
}

const Avatar& Humanoid() {
  static const std::shared_ptr<const Avatar> avatar = MakeHumanoid();
  return *avatar;
}

TEST(MakeHumanoidSkeleton, HasEveryHAnimJointUnderItsName) {
  const auto skeleton = MakeHumanoidSkeleton();
  for (J joint : AllHAnimJoints()) {
    const int index = skeleton->Find(joint);
    ASSERT_GE(index, 0) << HAnimName(joint);
    EXPECT_EQ(skeleton->joint(index).name, HAnimName(joint));
    const std::optional<J> parent = HAnimParent(joint);
    EXPECT_EQ(skeleton->joint(index).parent, parent ? skeleton->Find(*parent) : -1);
    // Rest frames aligned with the world, so clips can flex about x.
    EXPECT_TRUE(skeleton->rest_world()[index].linear().isIdentity(1e-15));
  }
}

TEST(MakeHumanoidSkeleton, LeftIsPlusXAndArmsHangTwentyDegrees) {
  const auto skeleton = MakeHumanoidSkeleton();
  for (J left :
       {J::kLHip, J::kLKnee, J::kLTalocrural, J::kLShoulder, J::kLElbow, J::kLRadiocarpal}) {
    EXPECT_GT(RestAt(*skeleton, left).x(), 0.0) << HAnimName(left);
    EXPECT_LT((RestAt(*skeleton, HAnimMirror(left)) -
               RestAt(*skeleton, left).cwiseProduct(Eigen::Vector3d(-1, 1, 1)))
                  .norm(),
              1e-12);
  }
  const Eigen::Vector3d arm =
      RestAt(*skeleton, J::kLRadiocarpal) - RestAt(*skeleton, J::kLShoulder);
  EXPECT_NEAR(std::atan2(arm.x(), -arm.y()) * 180.0 / std::numbers::pi, 20.0, 0.5);
  EXPECT_NEAR(arm.z(), 0.0, 1e-12);
  // Head above neck above shoulders above hips above knees above ankles.
  EXPECT_GT(RestAt(*skeleton, J::kSkullbase).y(), RestAt(*skeleton, J::kVc7).y());
  EXPECT_GT(RestAt(*skeleton, J::kVc7).y(), RestAt(*skeleton, J::kLShoulder).y() - 0.05);
  EXPECT_GT(RestAt(*skeleton, J::kLHip).y(), RestAt(*skeleton, J::kLKnee).y());
  EXPECT_GT(RestAt(*skeleton, J::kLKnee).y(), RestAt(*skeleton, J::kLTalocrural).y());
}

TEST(MakeHumanoid, StandsOnTheGroundAtTheMeasuredHeightFacingPlusZ) {
  for (double height : {1.75, 1.55}) {
    HumanoidMeasures measures;
    measures.height = height;
    const auto avatar = MakeHumanoid(measures);
    const Points& v = avatar->rest_vertices();
    EXPECT_NEAR(v.col(1).maxCoeff(), height, 0.02 * height);
    EXPECT_NEAR(v.col(1).minCoeff(), 0.0, 0.003);
    // The toes reach further forward than the heels reach back.
    double toe = 0.0;
    double heel = 0.0;
    for (int i = 0; i < v.rows(); ++i) {
      if (v(i, 1) > 0.05) continue;
      toe = std::max(toe, v(i, 2));
      heel = std::min(heel, v(i, 2));
    }
    EXPECT_GT(toe, 2.0 * -heel);
  }
}

TEST(MakeHumanoid, VertexCountIsModerate) {
  EXPECT_GE(Humanoid().num_vertices(), 3000);
  EXPECT_LE(Humanoid().num_vertices(), 8000);
}

/// A connected component of the triangle mesh: its triangles and vertices, and the
/// segment most of its vertices belong to.
struct Component {
  std::vector<int> triangles;
  std::set<int> vertices;
  J segment = J::kHumanoidRoot;
};

std::vector<Component> Components(const Avatar& avatar) {
  std::vector<int> root(avatar.num_vertices());
  std::iota(root.begin(), root.end(), 0);
  auto find = [&](int v) {
    while (root[v] != v) v = root[v] = root[root[v]];
    return v;
  };
  for (const Eigen::Vector3i& t : avatar.triangles()) {
    root[find(t[1])] = find(t[0]);
    root[find(t[2])] = find(t[0]);
  }
  std::map<int, Component> by_root;
  for (int i = 0; i < static_cast<int>(avatar.triangles().size()); ++i) {
    Component& component = by_root[find(avatar.triangles()[i][0])];
    component.triangles.push_back(i);
    for (int k = 0; k < 3; ++k) component.vertices.insert(avatar.triangles()[i][k]);
  }
  std::vector<Component> components;
  for (auto& [unused, component] : by_root) {
    std::map<J, int> votes;
    for (int v : component.vertices) ++votes[*avatar.vertex_segments()[v]];
    int best = 0;
    for (const auto& [segment, count] : votes) {
      if (count > best) {
        best = count;
        component.segment = segment;
      }
    }
    components.push_back(std::move(component));
  }
  return components;
}

TEST(MakeHumanoid, EverySegmentIsAClosedOutwardMesh) {
  const Avatar& avatar = Humanoid();
  const auto components = Components(avatar);
  // One mesh per body segment: all H-Anim joints but the root, which moves no segment.
  EXPECT_EQ(components.size(), static_cast<std::size_t>(kNumHAnimJoints - 1));
  std::set<J> segments;
  for (const Component& component : components) segments.insert(component.segment);
  EXPECT_EQ(segments.size(), components.size()) << "two meshes for one segment";
  EXPECT_EQ(segments.count(J::kHumanoidRoot), 0u);
  EXPECT_EQ(static_cast<int>(std::accumulate(
                components.begin(), components.end(), std::size_t{0},
                [](std::size_t n, const Component& c) { return n + c.vertices.size(); })),
            avatar.num_vertices())
      << "vertices used by no triangle";
  const Points& v = avatar.rest_vertices();
  for (const Component& component : components) {
    // Closed and consistently oriented: each directed edge once, its reverse once.
    std::map<std::pair<int, int>, int> directed;
    double volume = 0.0;
    for (int t : component.triangles) {
      const Eigen::Vector3i& tri = avatar.triangles()[t];
      for (int k = 0; k < 3; ++k) ++directed[{tri[k], tri[(k + 1) % 3]}];
      volume += v.row(tri[0]).dot(v.row(tri[1]).cross(v.row(tri[2]))) / 6.0;
    }
    for (const auto& [edge, count] : directed) {
      ASSERT_EQ(count, 1) << "edge " << edge.first << "-" << edge.second << " repeated";
      ASSERT_EQ(directed.count({edge.second, edge.first}), 1u)
          << "edge " << edge.first << "-" << edge.second << " is on the boundary";
    }
    EXPECT_GT(volume, 1e-5) << HAnimName(component.segment);
  }
}

TEST(MakeHumanoid, SegmentsOverlapTheirNeighboursAtTheJoints) {
  // Each joint between two segments lies inside both segments' meshes' bounding boxes:
  // a weak but independent check that the tubes reach across every joint.
  const Avatar& avatar = Humanoid();
  const Points& v = avatar.rest_vertices();
  const auto components = Components(avatar);
  for (J joint : {J::kLKnee, J::kLTalocrural, J::kLElbow, J::kLRadiocarpal, J::kVc7, J::kSkullbase,
                  J::kLHip, J::kVl5, J::kLShoulder}) {
    const Eigen::Vector3d at = RestAt(avatar.skeleton(), joint);
    J parent = *HAnimParent(joint);
    if (parent == J::kHumanoidRoot) parent = J::kSacroiliac;            // the root moves no segment
    if (parent == J::kVc7 && joint != J::kSkullbase) parent = J::kVl5;  // arms sit on the chest
    for (J segment : {joint, parent}) {
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9);
      Eigen::Vector3d hi = Eigen::Vector3d::Constant(-1e9);
      for (const Component& component : components) {
        if (component.segment != segment) continue;
        for (int i : component.vertices) {
          lo = lo.cwiseMin(v.row(i).transpose());
          hi = hi.cwiseMax(v.row(i).transpose());
        }
      }
      EXPECT_TRUE((at.array() > lo.array()).all() && (at.array() < hi.array()).all())
          << HAnimName(joint) << " outside the mesh of " << HAnimName(segment);
    }
  }
}

TEST(MakeHumanoid, WeightsArePositiveSumToOneAndBlendAtTheKnee) {
  const Avatar& avatar = Humanoid();
  const AvatarData& data = avatar.data();
  const int knee = avatar.skeleton().Find(J::kLKnee);
  int blended = 0;
  for (int i = 0; i < avatar.num_vertices(); ++i) {
    double sum = 0.0;
    for (int k = 0; k < kMaxInfluences; ++k) {
      if (data.influence_joints(i, k) < 0) continue;
      EXPECT_GE(data.influence_weights(i, k), 0.0);
      sum += data.influence_weights(i, k);
      if (data.influence_joints(i, k) == knee && data.influence_weights(i, k) > 0.1 &&
          data.influence_weights(i, k) < 0.9) {
        ++blended;
      }
    }
    EXPECT_NEAR(sum, 1.0, 1e-12) << "vertex " << i;
  }
  EXPECT_GT(blended, 20) << "no blend zone around the knee";
}

TEST(MakeHumanoid, RestPoseSkinningReproducesTheRestVertices) {
  const Avatar& avatar = Humanoid();
  std::vector<Eigen::Isometry3d> world;
  std::vector<Eigen::Isometry3d> skinning;
  Points skinned;
  ComputeJointWorld(avatar.skeleton(), RestPose(avatar.skeleton()), world);
  SkinVertices(avatar, world, skinning, skinned);
  EXPECT_LT((skinned - avatar.rest_vertices()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(MakeHumanoid, BendingTheKneeMovesTheCalfRigidlyAboutIt) {
  const Avatar& avatar = Humanoid();
  const Skeleton& skeleton = avatar.skeleton();
  const int knee = skeleton.Find(J::kLKnee);
  const int ankle = skeleton.Find(J::kLTalocrural);
  Pose pose = RestPose(skeleton);
  pose.rotations[knee] = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX());
  std::vector<Eigen::Isometry3d> world;
  std::vector<Eigen::Isometry3d> skinning;
  Points skinned;
  ComputeJointWorld(skeleton, pose, world);
  SkinVertices(avatar, world, skinning, skinned);
  const Eigen::RowVector3d center = skeleton.rest_world()[knee].translation().transpose();
  int calf = 0;
  double moved = 0.0;
  for (int i = 0; i < avatar.num_vertices(); ++i) {
    bool below_knee_only = true;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int joint = avatar.data().influence_joints(i, k);
      if (joint >= 0 && avatar.data().influence_weights(i, k) > 0.0 && joint != knee &&
          joint != ankle) {
        below_knee_only = false;
      }
    }
    if (!below_knee_only) continue;
    ++calf;
    EXPECT_NEAR((skinned.row(i) - center).norm(), (avatar.rest_vertices().row(i) - center).norm(),
                1e-9);
    moved = std::max(moved, (skinned.row(i) - avatar.rest_vertices().row(i)).norm());
  }
  EXPECT_GT(calf, 300);
  EXPECT_GT(moved, 0.5);  // the toes swing through a quarter circle of radius ~0.5 m
}

TEST(MakeHumanoid, RefusesImpossibleMeasures) {
  HumanoidMeasures measures;
  measures.height = -1.0;
  try {
    MakeHumanoid(measures);
    FAIL() << "accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("height"), std::string::npos) << error.what();
  }
  measures = {};
  measures.thigh_radius = std::nan("");
  EXPECT_THROW(MakeHumanoidSkeleton(measures), InputError);
}

}  // namespace
}  // namespace costume::sim
