// Simulation::SetAvatarFrozen (mode B, paper §5): the avatar's clock stops while the cloth
// keeps simulating, and resumes from where it stopped. Oracle: the avatar's pose is a
// function of its clock alone, so a never-frozen run posed at the same clock time must have
// the same skin.
#include <gtest/gtest.h>

#include "assets/scene_file.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim {
namespace {

SceneDescription Garment() {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  scene.avatar->motion.fit_time = 0.1;  // the walk starts at once: the skin moves every frame
  scene.avatar->motion.blend_time = 0.05;
  return scene;
}

TEST(AvatarFreeze, FrozenAvatarHoldsStillWhileTheClothMovesAndResumesWhereItStopped) {
  auto frozen = Simulation::Build(Garment());
  auto reference = Simulation::Build(Garment());
  const double h = frozen->step();
  for (int f = 0; f < 20; ++f) frozen->AdvanceFrame();
  frozen->SetAvatarFrozen(true);
  const double t_frozen = frozen->avatar_time();
  EXPECT_NEAR(t_frozen, 20 * h, 1e-12);
  const Points skin = frozen->avatar()->vertices();
  const Points cloth = frozen->state().positions;
  for (int f = 0; f < 10; ++f) frozen->AdvanceFrame();
  EXPECT_EQ(frozen->avatar_time(), t_frozen);
  EXPECT_EQ(frozen->avatar()->vertices(), skin);             // the body did not move
  EXPECT_GT((frozen->state().positions - cloth).norm(), 0);  // the cloth did
  EXPECT_NEAR(frozen->state().time, 30 * h, 1e-12);

  frozen->SetAvatarFrozen(false);
  for (int f = 0; f < 5; ++f) frozen->AdvanceFrame();
  for (int f = 0; f < 25; ++f) reference->AdvanceFrame();
  EXPECT_NEAR(frozen->avatar_time(), 25 * h, 1e-12);
  EXPECT_LT((frozen->avatar()->vertices() - reference->avatar()->vertices()).cwiseAbs().maxCoeff(),
            1e-9);
  EXPECT_GT((reference->avatar()->vertices() - skin).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(AvatarFreeze, NeverFrozenRunsAreUnchangedBitForBit) {
  auto a = Simulation::Build(Garment());
  auto b = Simulation::Build(Garment());
  b->SetAvatarFrozen(false);  // a no-op switch must not disturb anything
  for (int f = 0; f < 10; ++f) {
    a->AdvanceFrame();
    b->AdvanceFrame();
  }
  EXPECT_EQ(a->state().positions, b->state().positions);
  EXPECT_EQ(a->avatar_time(), a->state().time);
}

}  // namespace
}  // namespace costume::sim
