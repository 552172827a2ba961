#include "frontend/scene_mirror.h"

#include <gtest/gtest.h>

#include "frontend/catalog_source.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/arm_spread.h"
#include "sim_core/scene/simulation.h"
#include "tests/support/humanoid.h"

namespace costume::frontend {
namespace {

ClothFrame Frame(std::int64_t number, bool editing) {
  ClothFrame frame;
  frame.frame = number;
  frame.sim_time = number / 60.0;
  frame.editing = editing;
  return frame;
}

/// The avatar's vertices as an AvatarMotion of the same scene poses them at `t` [s], with
/// the arms spread by `spread` [rad].
std::vector<Eigen::Vector3f> PosedAt(const sim::SceneDescription& scene, double t,
                                     std::array<double, 2> spread = {0.0, 0.0}) {
  sim::AvatarMotionSettings settings = scene.avatar->motion;
  settings.arm_spread = spread;
  sim::AvatarMotion motion(scene.avatar->avatar, scene.avatar->clip, settings);
  motion.Evaluate(t);
  std::vector<Eigen::Vector3f> out;
  for (Eigen::Index i = 0; i < motion.vertices().rows(); ++i) {
    out.push_back(motion.vertices().row(i).transpose().cast<float>());
  }
  return out;
}

float MaxDistance(const std::vector<Eigen::Vector3f>& a, const std::vector<Eigen::Vector3f>& b) {
  EXPECT_EQ(a.size(), b.size());
  float d = 0.0f;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) d = std::max(d, (a[i] - b[i]).norm());
  return d;
}

class SceneMirrorTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { mirror_ = new SceneMirror(LoadScene("garment", "")); }
  static void TearDownTestSuite() { delete mirror_; }
  static SceneMirror* mirror_;
};
SceneMirror* SceneMirrorTest::mirror_ = nullptr;

TEST_F(SceneMirrorTest, HasTheServersClothAndAvatar) {
  // The server builds its model the same way: same particle count, same triangles.
  std::vector<sim::GarmentRange> garments;
  std::vector<sim::BodyAttachment> attachments;
  const auto model = sim::BuildSceneModel(mirror_->scene(), &garments, &attachments);
  EXPECT_EQ(mirror_->num_particles(), model->num_particles());
  ASSERT_EQ(mirror_->cloth_indices().size(), 3 * model->triangles().size());
  for (std::uint32_t index : mirror_->cloth_indices()) {
    ASSERT_LT(index, static_cast<std::uint32_t>(mirror_->num_particles()));
  }
  ASSERT_TRUE(mirror_->has_avatar());
  EXPECT_EQ(mirror_->avatar_indices().size(), 3 * mirror_->scene().avatar->avatar->triangles().size());
  EXPECT_TRUE(mirror_->Bounds().sizes().minCoeff() > 0.1);
}

// The view's floor lies under the avatar's feet where the scene stands it: the lowest rest
// skin vertex plus the avatar's position (MakeHuman's feet are at -0.8 m in its own frame);
// at 0 without an avatar.
TEST(SceneMirrorFloor, LiesUnderTheAvatarsFeet) {
  sim::SceneDescription scene = LoadScene("garment", "");
  scene.avatar->motion.posture.root_translation = Eigen::Vector3d(0.3, -0.8, 0.1);
  const SceneMirror raised(scene);
  const auto& rest = scene.avatar->avatar->rest_vertices();
  EXPECT_NEAR(raised.floor_height(), rest.col(1).minCoeff() - 0.8, 1e-4);
  EXPECT_EQ(SceneMirror(LoadScene("hang", "")).floor_height(), 0.0f);
}

TEST_F(SceneMirrorTest, TheAvatarWalksInModeAAndStandsInModeB) {
  SceneMirror& m = *mirror_;
  m.Follow(Frame(0, false));
  for (int f = 1; f <= 90; ++f) m.Follow(Frame(f, false));
  EXPECT_NEAR(m.avatar_time(), 1.5, 1e-9);
  EXPECT_LT(MaxDistance(m.avatar_vertices(), PosedAt(m.scene(), 1.5)), 1e-5f);
  for (int f = 91; f <= 150; ++f) m.Follow(Frame(f, true));  // 1 s of editing
  EXPECT_NEAR(m.avatar_time(), 1.5, 1e-9);
  for (int f = 151; f <= 180; ++f) m.Follow(Frame(f, false));  // resumes where it stopped
  EXPECT_NEAR(m.avatar_time(), 2.0, 1e-9);
  EXPECT_LT(MaxDistance(m.avatar_vertices(), PosedAt(m.scene(), 2.0)), 1e-5f);
  m.Follow(Frame(0, false));  // STOP: the server rebuilt the scene
  EXPECT_NEAR(m.avatar_time(), 0.0, 1e-9);
}

// The server turns out an arm its clip holds into the hip (sim::FindArmSpread): the view
// shows the arm where the cloth meets it, not where the clip has it, and chooses again when
// the server rebuilds in a posture set since.
TEST(SceneMirrorArms, AreSpreadAsTheServersAndChosenAgainAfterARebuild) {
  sim::SceneDescription scene = LoadScene("garment", "");
  scene.avatar->clip = test::ArmInClip(24.0);
  SceneMirror m(scene);
  const sim::ArmSpreadFit fit =
      sim::FindArmSpread(scene.avatar->avatar, scene.avatar->clip, scene.avatar->motion);
  ASSERT_GT(fit.angle[0], 0.0);
  EXPECT_EQ(m.arm_spread().angle, fit.angle);
  for (int f = 0; f <= 90; ++f) m.Follow(Frame(f, false));
  EXPECT_LT(MaxDistance(m.avatar_vertices(), PosedAt(scene, 1.5, fit.angle)), 1e-5f);
  EXPECT_GT(MaxDistance(m.avatar_vertices(), PosedAt(scene, 1.5)), 0.02f);  // the clip's arm

  m.SetPosture({{"r_elbow", Eigen::Vector3d(60.0, 0.0, 0.0)}}, 0.0);
  for (int f = 91; f <= 150; ++f) m.Follow(Frame(f, false));
  for (int f = 0; f <= 90; ++f) m.Follow(Frame(f, false));  // STOP: rebuilt in the posture
  const sim::SceneDescription& posed = m.scene();
  const sim::ArmSpreadFit refit =
      sim::FindArmSpread(posed.avatar->avatar, posed.avatar->clip, posed.avatar->motion);
  EXPECT_EQ(m.arm_spread().angle, refit.angle);
  EXPECT_LT(MaxDistance(m.avatar_vertices(), PosedAt(posed, 1.5, refit.angle)), 1e-5f);

  // A spread the designer gives: reached over the posture's transition, kept by a rebuild.
  sim::ArmSpreadRequest given;
  given.kind = sim::ArmSpreadRequest::Kind::kGiven;
  given.angle = {0.1, 0.2};
  m.SetPosture({}, 0.0, given);
  for (int f = 91; f <= 150; ++f) m.Follow(Frame(f, false));
  EXPECT_FALSE(m.scene().avatar->auto_arm_spread);
  EXPECT_EQ(m.arm_spread().angle, given.angle);
  EXPECT_LT(MaxDistance(m.avatar_vertices(), PosedAt(m.scene(), 2.5, given.angle)), 1e-5f);
  for (int f = 0; f <= 90; ++f) m.Follow(Frame(f, false));
  EXPECT_LT(MaxDistance(m.avatar_vertices(), PosedAt(m.scene(), 1.5, given.angle)), 1e-5f);
}

TEST_F(SceneMirrorTest, BuiltInLoadsChangeTheMirroredScene) {
  auto catalog = MakeBuiltInCatalog();
  sim::SceneDescription scene = mirror_->scene();
  catalog->ApplyToScene(EntryKind::kCostume, {0, "cape", "", {}}, scene);
  ASSERT_EQ(scene.garments.size(), 1u);
  EXPECT_EQ(scene.garments[0].pattern, "cape");
  catalog->ApplyToScene(EntryKind::kAnimation, {0, "dance", "", {}}, scene);
  ASSERT_TRUE(scene.avatar->clip);
  const SceneMirror cape(scene);
  EXPECT_GT(cape.num_particles(), 0);
  EXPECT_NE(cape.cloth_indices(), mirror_->cloth_indices());

  sim::SceneDescription hang = LoadScene("hang", "");
  EXPECT_THROW(catalog->ApplyToScene(EntryKind::kCostume, {0, "skirt", "", {}}, hang),
               sim::InputError);
}

}  // namespace
}  // namespace costume::frontend
