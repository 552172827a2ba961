// ColliderMemo: a simulation built again for the same avatar (a server's STOP, a new fabric)
// keeps the superquadric collider, with the drawings of its maps, instead of fitting it and
// drawing every map again. Oracle: a simulation built without the memo, which must step
// exactly as the one that reuses the kept collider.
#include "sim_core/scene/body_colliders.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "assets/scene_file.h"
#include "sim_core/collision/superquadric_collider.h"
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
  scene.avatar->collision = BodyCollisionMethod::kMesh;
  ColliderMemo memo;
  auto running = Simulation::Build(scene, nullptr, &memo);
  running->AdvanceFrame();
  CollisionSettings fast = CollisionSettingsOf(scene);
  fast.method = BodyCollisionMethod::kSuperquadric;  // a new method: a new collider
  running->SetCollision(fast, &memo);
  EXPECT_EQ(memo.num_builds(), 2);
  ApplyCollisionSettings(fast, scene);
  const BodyCollider* in_use = running->body_collider();
  running.reset();
  auto stopped = Simulation::Build(scene, nullptr, &memo);
  EXPECT_EQ(memo.num_builds(), 2);
  EXPECT_EQ(stopped->body_collider(), in_use);
}

// A new map memory mid-walk is given to the running collider: nothing is fitted, the store
// starts empty with the new budget, and the body keeps its motion, so the cloth moves bit
// for bit as in a simulation built with that memory from the start. (A new collider would
// take the next pose without a velocity, and the cloth would move otherwise.)
TEST(ColliderMemo, ANewMapMemoryIsGivenToTheRunningCollider) {
  SceneDescription scene = WalkingSkirt();
  ColliderMemo memo;
  auto running = Simulation::Build(scene, nullptr, &memo);
  for (int f = 0; f < 40; ++f) running->AdvanceFrame();  // into the walk, past the fit
  const BodyCollider* in_use = running->body_collider();
  CollisionSettings smaller = CollisionSettingsOf(scene);
  smaller.superquadric_map_mb = 32.0;
  running->SetCollision(smaller, &memo);
  EXPECT_EQ(memo.num_builds(), 1);
  ASSERT_EQ(running->body_collider(), in_use);
  const auto& store = dynamic_cast<const SuperquadricCollider&>(*in_use).map_cache_stats();
  EXPECT_EQ(store.budget_bytes, std::size_t{32} << 20);
  EXPECT_EQ(store.bytes_used, 0u);
  ApplyCollisionSettings(smaller, scene);
  auto built = Simulation::Build(scene);
  for (int f = 0; f < 40; ++f) built->AdvanceFrame();
  for (int f = 0; f < 20; ++f) {
    running->AdvanceFrame();
    built->AdvanceFrame();
  }
  EXPECT_GT(store.bytes_used, 0u);
  EXPECT_EQ((running->state().positions - built->state().positions).cwiseAbs().maxCoeff(), 0.0);
}

// Only another avatar builds a new superquadric collider: friction, thickness and map
// memory are given to the kept one, which then has the new store's budget, empty. A mesh
// collider is built each time and not kept.
TEST(ColliderMemo, AnotherAvatarBuildsAnewOtherSettingsAreGivenToTheKeptCollider) {
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
  const auto& superquadrics = dynamic_cast<const SuperquadricCollider&>(*kept);
  ASSERT_GT(superquadrics.map_cache_stats().bytes_used, 0u);  // the rest pose's drawings
  EXPECT_EQ(memo.Find(BodyCollisionMethod::kSuperquadric, avatar, thicker, 32.0), kept);
  EXPECT_EQ(memo.num_builds(), 1);
  EXPECT_EQ(superquadrics.map_cache_stats().budget_bytes, std::size_t{32} << 20);
  EXPECT_EQ(superquadrics.map_cache_stats().bytes_used, 0u);
  const std::shared_ptr<const Avatar> other = Avatar::Create(avatar->data());
  EXPECT_NE(memo.Find(BodyCollisionMethod::kSuperquadric, other, thicker, 32.0), kept);
  EXPECT_EQ(memo.num_builds(), 2);
  const std::shared_ptr<BodyCollider> mesh =
      memo.Find(BodyCollisionMethod::kMesh, avatar, settings, 64.0);
  EXPECT_NE(memo.Find(BodyCollisionMethod::kMesh, avatar, settings, 64.0), mesh);
  EXPECT_EQ(memo.num_builds(), 4);
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
