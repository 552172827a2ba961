// ColliderMemo: a simulation built again for the same avatar (a server's STOP, a new fabric)
// keeps the superquadric collider, with the drawings of its maps, instead of fitting it and
// drawing every map again. Oracle: a simulation built without the memo, which must step
// exactly as the one that reuses the kept collider.
#include "sim_core/scene/body_colliders.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "assets/scene_file.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim {
namespace {

/// The built-in skirt on the built-in humanoid walking, superquadric collision.
SceneDescription WalkingSkirt() {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  scene.avatar->collision = BodyCollisionMethod::kSuperquadric;
  return scene;
}

/// Maps drawn over `frames` frames of `simulation` (the last step of each: the walk takes
/// one step a frame).
int MapsDrawn(Simulation& simulation, int frames) {
  int drawn = 0;
  for (int f = 0; f < frames; ++f) {
    simulation.AdvanceFrame();
    drawn += simulation.body_collider()->stats().num_maps_drawn;
  }
  return drawn;
}

// Over the fit and the walk's first pass a new collider draws every map a frame needs; one
// kept from a simulation that played them draws almost none, and the cloth moves exactly as
// with the new collider (the drawings it reads are the ones it would draw).
TEST(ColliderMemo, ARebuiltSimulationKeepsTheColliderAndStepsAsANewOne) {
  const SceneDescription scene = WalkingSkirt();
  // The fit (0.5 s) and one pass of the walk (1.1 s), at 60 Hz.
  const int frames = 30 + 66 + 2;
  ColliderMemo memo;
  auto first = Simulation::Build(scene, nullptr, &memo);
  MapsDrawn(*first, frames + 5);
  auto rebuilt = Simulation::Build(scene, nullptr, &memo);
  first.reset();
  EXPECT_EQ(memo.num_builds(), 1);
  auto fresh = Simulation::Build(scene);
  int drawn_kept = 0, drawn_fresh = 0;
  double largest_difference = 0.0;
  for (int f = 0; f < frames; ++f) {
    drawn_kept += MapsDrawn(*rebuilt, 1);
    drawn_fresh += MapsDrawn(*fresh, 1);
    largest_difference = std::max(
        largest_difference,
        (rebuilt->state().positions - fresh->state().positions).cwiseAbs().maxCoeff());
  }
  EXPECT_GT(drawn_fresh, 500);
  EXPECT_LT(drawn_kept, drawn_fresh / 20) << drawn_kept << " against " << drawn_fresh;
  EXPECT_EQ(largest_difference, 0.0);
}

// A collider built for new collision settings while the scene runs (the server's
// SET_COLLISION) is kept for the rebuild that follows (a STOP in those settings).
TEST(ColliderMemo, ACollisionChangeKeepsItsColliderForTheNextBuild) {
  SceneDescription scene = WalkingSkirt();
  ColliderMemo memo;
  auto running = Simulation::Build(scene, nullptr, &memo);
  running->AdvanceFrame();
  CollisionSettings smaller = CollisionSettingsOf(scene);
  smaller.superquadric_map_mb = 32.0;  // a new store: a new collider
  running->SetCollision(smaller, &memo);
  EXPECT_EQ(memo.num_builds(), 2);
  ApplyCollisionSettings(smaller, scene);
  const BodyCollider* in_use = running->body_collider();
  running.reset();
  auto stopped = Simulation::Build(scene, nullptr, &memo);
  EXPECT_EQ(memo.num_builds(), 2);
  EXPECT_EQ(stopped->body_collider(), in_use);
}

// Only the same avatar with the same map memory gets the kept collider (with the thickness
// and friction asked for, which it takes in place); a mesh collider is built each time and
// not kept.
TEST(ColliderMemo, AnotherAvatarOrOtherSettingsBuildAnew) {
  const SceneDescription scene = WalkingSkirt();
  const std::shared_ptr<const Avatar> avatar = scene.avatar->avatar;
  const BodyCollisionSettings settings;
  ColliderMemo memo;
  const std::shared_ptr<BodyCollider> kept =
      memo.Find(BodyCollisionMethod::kSuperquadric, avatar, settings, 64.0);
  EXPECT_EQ(memo.Find(BodyCollisionMethod::kSuperquadric, avatar, settings, 64.0), kept);
  BodyCollisionSettings grippy = settings;
  grippy.friction = 1.5;
  EXPECT_EQ(memo.Find(BodyCollisionMethod::kSuperquadric, avatar, grippy, 64.0), kept);
  EXPECT_EQ(memo.num_builds(), 1);
  BodyCollisionSettings thicker = settings;
  thicker.thickness = 0.008;
  EXPECT_EQ(memo.Find(BodyCollisionMethod::kSuperquadric, avatar, thicker, 64.0), kept);
  EXPECT_EQ(memo.num_builds(), 1);
  EXPECT_NE(memo.Find(BodyCollisionMethod::kSuperquadric, avatar, thicker, 32.0), kept);
  EXPECT_EQ(memo.num_builds(), 2);
  const std::shared_ptr<const Avatar> other = Avatar::Create(avatar->data());
  EXPECT_NE(memo.Find(BodyCollisionMethod::kSuperquadric, other, thicker, 32.0), kept);
  EXPECT_EQ(memo.num_builds(), 3);
  const std::shared_ptr<BodyCollider> mesh =
      memo.Find(BodyCollisionMethod::kMesh, avatar, settings, 64.0);
  EXPECT_NE(memo.Find(BodyCollisionMethod::kMesh, avatar, settings, 64.0), mesh);
  EXPECT_EQ(memo.num_builds(), 5);
}

// A designer comparing the methods on one avatar: back from the mesh method, the
// superquadric collider is the one kept, not fitted again; another avatar's is let go even
// when a mesh collider is asked for.
TEST(ColliderMemo, TheSuperquadricColliderStaysThroughAMeshCollidersTime) {
  const std::shared_ptr<const Avatar> avatar = WalkingSkirt().avatar->avatar;
  ColliderMemo memo;
  const std::shared_ptr<BodyCollider> kept =
      memo.Find(BodyCollisionMethod::kSuperquadric, avatar, {}, 64.0);
  memo.Find(BodyCollisionMethod::kMesh, avatar, {}, 64.0);
  EXPECT_EQ(memo.Find(BodyCollisionMethod::kSuperquadric, avatar, {}, 64.0), kept);
  EXPECT_EQ(memo.num_builds(), 2);
  const std::weak_ptr<BodyCollider> watched = kept;
  const std::shared_ptr<const Avatar> other = Avatar::Create(avatar->data());
  memo.Find(BodyCollisionMethod::kMesh, other, {}, 64.0);
  EXPECT_EQ(watched.use_count(), 1);  // only `kept` here holds it now
}

}  // namespace
}  // namespace costume::sim
