// A frame is split into more steps where the avatar's skin near the cloth moves farther than
// AvatarSpec::max_skin_travel within a step (Simulation::AdvanceFrame): collision is tested
// where a step starts and ends, so a limb crossing cloth within one step leaves it threaded
// round the limb. Oracles: a swung thigh's knee joint's chord a frame from the skeleton; the
// strain of a hem spread over a limb, and a spring threaded round it from the true skinned
// mesh (its midpoint deep inside the body while both ends are outside).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "assets/scene_file.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"
#include "tests/support/threaded_cloth.h"

namespace costume::sim {
namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

/// The posture `simulation`'s scene holds, one rotation per joint.
Pose PostureOf(const Simulation& simulation) {
  Pose posture = simulation.scene().avatar->motion.posture;
  posture.rotations.resize(simulation.avatar()->avatar().skeleton().num_joints(),
                           Eigen::Quaterniond::Identity());
  return posture;
}

/// The built-in skirt on the standing built-in humanoid, fitted briefly.
SceneDescription StandingSkirt(double max_skin_travel) {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  scene.avatar->clip = nullptr;
  scene.avatar->motion.fit_time = 0.2;
  scene.avatar->max_skin_travel = max_skin_travel;
  scene.duration = 2.0;
  return scene;
}

// The left thigh swings 60° forward in 0.25 s (15 frames, 4° a frame): the knee joint, at
// L from the hip joint, moves 2·L·sin(2°) a frame, and the knee's skin under the skirt at
// least as far, so a 1 cm limit needs at least that over 1 cm steps; no skin moves farther
// than the farthest vertex of the whole body, an upper bound. Standing still again, one.
TEST(FastLimbs, AFrameInWhichTheSkinNearTheClothMovesFartherIsSplit) {
  constexpr double kLimit = 0.01;
  auto simulation = Simulation::Build(StandingSkirt(kLimit));
  for (int f = 0; f < 12; ++f) EXPECT_EQ(simulation->AdvanceFrame().steps, 1) << "frame " << f;
  const Skeleton& skeleton = simulation->avatar()->avatar().skeleton();
  const int hip = skeleton.Find(HAnimJoint::kLHip), knee = skeleton.Find(HAnimJoint::kLKnee);
  ASSERT_GE(hip, 0);
  ASSERT_GE(knee, 0);
  const std::vector<Eigen::Isometry3d>& joints = simulation->avatar()->joint_world();
  const double thigh = (joints[knee].translation() - joints[hip].translation()).norm();
  // The skirt reaches below the knee joint, so skin at the knee is near it.
  ASSERT_LT(simulation->state().positions.col(1).minCoeff(), joints[knee].translation().y());
  const double knee_chord = 2.0 * thigh * std::sin(0.5 * 4.0 * kDegree);
  const int fewest = static_cast<int>(std::ceil(knee_chord / kLimit));
  Pose swung = PostureOf(*simulation);
  swung.rotations[hip] =
      Eigen::Quaterniond(Eigen::AngleAxisd(-60.0 * kDegree, Eigen::Vector3d::UnitX()));
  ASSERT_TRUE(simulation->SetPosture(swung, 0.25));
  for (int f = 0; f < 14; ++f) {
    const Points before = simulation->avatar()->vertices();
    const int steps = simulation->AdvanceFrame().steps;
    const double farthest = (simulation->avatar()->vertices() - before).rowwise().norm().maxCoeff();
    EXPECT_GE(steps, fewest) << "frame " << f;
    EXPECT_LE(steps, static_cast<int>(std::ceil(farthest / kLimit))) << "frame " << f;
  }
  for (int f = 0; f < 3; ++f) simulation->AdvanceFrame();
  EXPECT_EQ(simulation->AdvanceFrame().steps, 1);
  std::printf("thigh %.0f mm: at least %d steps a frame\n", 1e3 * thigh, fewest);
}

// The whole body slides 0.5 m in 0.25 s (33 mm a frame) and takes the skirt with it, which
// hangs from it: the skin moves no faster relative to the body's root, so nothing is split.
TEST(FastLimbs, TheWholeBodyTravellingDoesNotSplitAFrame) {
  auto simulation = Simulation::Build(StandingSkirt(0.01));
  for (int f = 0; f < 12; ++f) simulation->AdvanceFrame();
  Pose moved = PostureOf(*simulation);
  moved.root_translation += Eigen::Vector3d(0.0, 0.0, 0.5);
  ASSERT_TRUE(simulation->SetPosture(moved, 0.25));
  const Points before = simulation->avatar()->vertices();
  for (int f = 0; f < 14; ++f) EXPECT_EQ(simulation->AdvanceFrame().steps, 1) << "frame " << f;
  EXPECT_GT((simulation->avatar()->vertices() - before).rowwise().norm().minCoeff(), 0.4);
}

// The same slide towards a curtain pinned in the room just in front of the body: the curtain
// does not go with the body, so the skin meets it at the root's speed too, and frames are
// split (before, judged relative to the root as for the skirt, none was). At most as many
// steps as the body's fastest vertex needs.
TEST(FastLimbs, TheBodyTravellingTowardsClothPinnedInTheRoomSplitsFrames) {
  SceneDescription scene = StandingSkirt(0.01);
  GarmentSpec curtain;
  curtain.name = "curtain";
  curtain.material = scene.garments.front().material;
  LatticePanel panel;
  panel.origin = Eigen::Vector3d(-0.3, 0.6, 0.35);  // in the xy plane, 35 cm before the body
  panel.u_axis = Eigen::Vector3d::UnitX();
  panel.v_axis = Eigen::Vector3d::UnitY();
  panel.width = 0.6;
  panel.height = 0.6;
  panel.cols = panel.rows = 7;
  for (int j = 0; j < panel.cols; ++j) {  // its top row, held in the room
    curtain.pin_points.push_back(panel.origin + panel.height * panel.v_axis +
                                 0.1 * j * panel.u_axis);
  }
  curtain.panel = panel;
  scene.garments.push_back(curtain);
  auto simulation = Simulation::Build(scene);
  for (int f = 0; f < 12; ++f) EXPECT_EQ(simulation->AdvanceFrame().steps, 1) << "frame " << f;
  Pose moved = PostureOf(*simulation);
  moved.root_translation += Eigen::Vector3d(0.0, 0.0, 0.5);
  ASSERT_TRUE(simulation->SetPosture(moved, 0.25));
  int most = 0;
  for (int f = 0; f < 14; ++f) {
    const Points before = simulation->avatar()->vertices();
    const int steps = simulation->AdvanceFrame().steps;
    const double farthest = (simulation->avatar()->vertices() - before).rowwise().norm().maxCoeff();
    EXPECT_LE(steps, std::max(1, static_cast<int>(std::ceil(farthest / 0.01)))) << "frame " << f;
    most = std::max(most, steps);
  }
  // The slide's mean speed alone, 33 mm a frame, needs 4 steps of 1 cm.
  EXPECT_GE(most, 4);
  std::printf("body sliding towards a curtain pinned in the room: up to %d steps a frame\n",
              most);
}

// Turning the head moves skin far above the skirt's reach: no split, however fast.
TEST(FastLimbs, SkinFarFromTheClothDoesNotSplitAFrame) {
  auto simulation = Simulation::Build(StandingSkirt(0.002));
  for (int f = 0; f < 12; ++f) simulation->AdvanceFrame();
  Pose turned = PostureOf(*simulation);
  const int skullbase = simulation->avatar()->avatar().skeleton().Find(HAnimJoint::kSkullbase);
  ASSERT_GE(skullbase, 0);
  turned.rotations[skullbase] =
      Eigen::Quaterniond(Eigen::AngleAxisd(1.5, Eigen::Vector3d::UnitY()));
  ASSERT_TRUE(simulation->SetPosture(turned, 0.1));
  const Points before = simulation->avatar()->vertices();
  for (int f = 0; f < 6; ++f) EXPECT_EQ(simulation->AdvanceFrame().steps, 1) << "frame " << f;
  // The head did move, by more than the limit a frame.
  EXPECT_GT((simulation->avatar()->vertices() - before).rowwise().norm().maxCoeff(), 6 * 0.002);
}

// Measuring the skin's travel poses the avatar ahead; a frame it does not split must come
// out bit for bit as with the measure off.
TEST(FastLimbs, AnUnsplitFrameIsBitForBitTheFrameWithTheMeasureOff) {
  SceneDescription off = assets::LoadBuiltInScene("garment");
  off.avatar->max_skin_travel = 0.0;
  SceneDescription loose = off;
  loose.avatar->max_skin_travel = 1.0;  // never reached by the walk
  auto a = Simulation::Build(off);
  auto b = Simulation::Build(loose);
  for (int f = 0; f < 45; ++f) {
    EXPECT_EQ(a->AdvanceFrame().steps, 1);
    EXPECT_EQ(b->AdvanceFrame().steps, 1);
  }
  EXPECT_EQ(a->state().positions, b->state().positions);
  EXPECT_EQ(a->state().velocities, b->state().velocities);
}

/// The built-in skirt, `resolution` particles round, on the built-in humanoid kicking for
/// `seconds` after the fit: the largest structural strain and the frames with a spring
/// threaded round the body.
struct KickResult {
  double max_strain = 0.0;
  int threaded_frames = 0;
  int steps = 0;
};

KickResult Kick(double max_skin_travel, int resolution, double seconds) {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  auto humanoid = scene.avatar->avatar;
  scene.avatar->clip =
      std::make_shared<const Clip>(MakeBuiltInClip("kick", humanoid->shared_skeleton()));
  scene.avatar->max_skin_travel = max_skin_travel;
  scene.duration = scene.avatar->motion.fit_time + seconds;
  scene.garments[0].pattern_resolution = resolution;
  // A soft cotton (300 N/m), where the knee's spread of the hem shows in one step a frame.
  Material soft = NamedMaterial("cotton");
  soft.name = "soft_cotton";
  soft.stretch_stiffness = soft.shear_stiffness = 300.0;
  scene.materials.push_back(soft);
  scene.garments[0].material = soft.name;
  auto simulation = Simulation::Build(scene);
  MeshDistance skin("humanoid", simulation->avatar()->vertices(), humanoid->triangles());
  KickResult result;
  for (int f = 0; f < simulation->num_frames(); ++f) {
    result.steps += simulation->AdvanceFrame().steps;
    const Points& x = simulation->state().positions;
    skin.Update(simulation->avatar()->vertices());
    result.max_strain = std::max(result.max_strain, StructuralStrain(simulation->model(), x).max);
    if (test::CountThreadedSprings(simulation->model(), x, skin) > 0) ++result.threaded_frames;
  }
  std::printf("kick, %d around, max_skin_travel %.0f mm: largest strain %.0f %%, %d frames "
              "threaded, %d steps\n", resolution, 1e3 * max_skin_travel, 100 * result.max_strain,
              result.threaded_frames, result.steps);
  return result;
}

// The kicking leg's skin near the skirt moves up to 15–20 cm a frame (4 steps at 5 cm). In
// one step a frame the knee reaches the hem within the step, and the position correction
// spreads the hem over the knee past the strain limit's 10 % (16 % in a soft cotton). Split
// into steps of at most 5 cm the contacts catch the hem as the knee comes (10 %).
TEST(FastLimbs, SplitFramesKeepTheKickingKneeFromSpreadingTheSkirtsHem) {
  const KickResult whole = Kick(0.0, 90, 4.0);
  const KickResult split = Kick(0.05, 90, 4.0);
  EXPECT_GT(whole.max_strain, 0.13);  // the failure the split is for
  EXPECT_LT(split.max_strain, 0.11);
  EXPECT_EQ(split.threaded_frames, 0);
  EXPECT_GT(split.steps, whole.steps);
}

}  // namespace
}  // namespace costume::sim
