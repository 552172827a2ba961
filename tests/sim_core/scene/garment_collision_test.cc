// A garment on the walking and kicking avatar (paper §4, §6; mode A): the skirt is fitted to
// the built-in humanoid, and to the MakeHuman body of ../shared/data when present, and
// follows the clip; the oracle is the true skinned mesh (MeshDistance's penetration depth,
// inside by winding number), not the collider's own proxy.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "assets/makehuman_import.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/self_collision.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"
#include "tests/support/shared_data.h"

namespace costume::sim {
namespace {

struct RunResult {
  double max_depth = 0.0;        // deepest particle inside the skin over the run [m]
  double max_strain = 0.0;       // after fitting [-]
  double fitted_speed = 0.0;     // fastest particle when fitting ends [m/s]
  int rolled_back = 0;
  // Edges of the skirt through one of its triangles, the most in any frame sampled during
  // the clip (every tenth), and at the end; counted only when asked (brute force).
  int most_crossing_edges = 0;
  int crossing_edges_at_end = 0;
};

struct GarmentOptions {
  bool self_collision = false;
  bool count_crossings = false;
  std::string pattern = "skirt";  // a built-in garment
  int resolution = 64;            // its particles around
};

/// A built-in garment (the skirt unless `options` say otherwise) on `body` (the built-in
/// humanoid when null), playing the built-in `clip` (retargeted by H-Anim names) for
/// `seconds` after the fit.
RunResult RunGarment(BodyCollisionMethod method, const std::string& clip, double seconds,
                     std::shared_ptr<const Avatar> body = nullptr, GarmentOptions options = {}) {
  static const std::shared_ptr<const Avatar> builtin = MakeHumanoid();
  const std::shared_ptr<const Avatar> humanoid = body ? body : builtin;
  SceneDescription scene;
  scene.source = "garment_collision_test";
  scene.solver.method = SolverMethod::kMultigrid;
  AvatarSpec avatar;
  avatar.avatar = humanoid;
  if (clip != "none") {
    avatar.clip = std::make_shared<const Clip>(MakeBuiltInClip(clip, builtin->shared_skeleton()));
  }
  avatar.collision = method;
  scene.avatar = avatar;
  scene.duration = avatar.motion.fit_time + seconds;
  scene.effects.self_collision = options.self_collision;
  GarmentSpec garment;
  garment.name = options.pattern;
  garment.pattern = options.pattern;
  garment.pattern_resolution = options.resolution;
  scene.garments.push_back(garment);

  auto simulation = Simulation::Build(scene);
  MeshDistance skin("humanoid", simulation->avatar()->vertices(), humanoid->triangles());
  std::vector<bool> attached(simulation->model().num_particles(), false);
  for (const BodyAttachment& a : simulation->attachments()) attached[a.particle] = true;
  const int fit_frames = static_cast<int>(avatar.motion.fit_time * scene.frame_rate);
  RunResult result;
  for (int f = 0; f < simulation->num_frames(); ++f) {
    result.rolled_back += simulation->AdvanceFrame().rolled_back_steps;
    const Points& x = simulation->state().positions;
    skin.Update(simulation->avatar()->vertices());
    for (Eigen::Index p = 0; p < x.rows(); ++p) {
      if (!attached[p]) result.max_depth = std::max(result.max_depth, skin.PenetrationDepth(x.row(p).transpose(), 0.1));
    }
    if (f == fit_frames - 1) {
      result.fitted_speed = simulation->state().velocities.rowwise().norm().maxCoeff();
    }
    if (f >= fit_frames) {
      result.max_strain = std::max(result.max_strain, StructuralStrain(simulation->model(), x).max);
    }
    const bool last = f + 1 == simulation->num_frames();
    if (options.count_crossings && f >= fit_frames && ((f - fit_frames) % 10 == 0 || last)) {
      const int crossing = CountCrossingEdges(simulation->model(), x);
      result.most_crossing_edges = std::max(result.most_crossing_edges, crossing);
      if (last) result.crossing_edges_at_end = crossing;
    }
  }
  std::printf("%s, %s %d around, %s, %s: deepest particle %.2f mm inside the skin, "
              "max strain %.1f %%, speed after fitting %.3f m/s\n",
              humanoid->name().c_str(), options.pattern.c_str(), options.resolution,
              BodyCollisionMethodName(method), clip.c_str(), 1e3 * result.max_depth,
              100 * result.max_strain, result.fitted_speed);
  return result;
}

// The accurate method keeps every particle within 2 mm of the true skin while the avatar
// walks and kicks, the bound. Walking stretches the skirt little; a 70° kick inside
// a knee-length skirt must stretch its hem locally (62 % measured, a property of the
// garment's cut, not of collision), so strain is bounded for the walk only.
TEST(GarmentCollision, MeshMethodKeepsTheSkirtOutOfTheWalkingAndKickingBody) {
  for (const char* clip : {"walk", "kick"}) {
    const RunResult run = RunGarment(BodyCollisionMethod::kMesh, clip, 2.0);
    EXPECT_LE(run.max_depth, 0.002) << clip;
    if (std::string(clip) == "walk") {
      EXPECT_LT(run.max_strain, 0.25);
    }
    EXPECT_EQ(run.rolled_back, 0) << clip;
  }
}

// The fast method too keeps every particle within 2 mm of the true skin while the avatar
// walks and kicks: its distance maps are redrawn from the skinned triangles every frame,
// joint shells hold the creases of bent joints, and cloth resting on a limb stays
// constrained (docs/collision.md, "Fast method"). The kick's strain is bounded loosely (the
// mesh method's is 66 %): above 100 % the leg has threaded through the skirt (843 % when
// only the predicted gap made contacts).
TEST(GarmentCollision, SuperquadricMethodKeepsTheSkirtOutOfTheWalkingAndKickingBody) {
  for (const char* clip : {"walk", "kick"}) {
    const RunResult run = RunGarment(BodyCollisionMethod::kSuperquadric, clip, 2.0);
    EXPECT_LE(run.max_depth, 0.002) << clip;
    EXPECT_LT(run.max_strain, std::string(clip) == "walk" ? 0.4 : 1.0) << clip;
    EXPECT_EQ(run.rolled_back, 0) << clip;
  }
}

// The same on MakeHuman's body (../shared/data), a single skinned mesh whose crotch linear
// blend skinning folds through itself: both methods keep every particle within 2 mm of the
// true skin walking, kicking and running. (Running, the benchmark's finer skirt went 10 mm
// into the body behind the bent knee, where skinning folds skin through skin, before the
// superquadric method counted it, docs/collision.md, "Other clips"; this coarser skirt
// stayed out either way.) For the superquadric method this needed the folded rays
// (the thigh's skin moved through the groin's) and ProjectOut's return from a pinch
// between the thighs (docs/collision.md). Walking, the skirt stretches little with either
// method (37 % and 14 % here; in the benchmark's finer skirts the superquadric method
// reached 265–510 % before its readings deeper than the step allows went to the skin
// triangles, 38–71 % since); the kick is not bounded (the superquadric method's hem
// reaches 140 % here, the mesh method's 43 %).
TEST(GarmentCollision, BothMethodsKeepTheSkirtOutOfTheWalkingKickingAndRunningMakeHumanBody) {
  namespace fs = std::filesystem;
  const fs::path mh = test::kSharedData / "makehuman" / "body";
  if (!fs::exists(mh / "base.obj")) {
    GTEST_SKIP() << "test data " << test::kSharedData << "/makehuman not present";
  }
  static const std::shared_ptr<const Avatar> body = assets::LoadMakeHumanAvatar(
      (mh / "base.obj").string(), (mh / "default.mhskel").string(),
      (mh / "default_weights.mhw").string());
  for (BodyCollisionMethod method : {BodyCollisionMethod::kMesh, BodyCollisionMethod::kSuperquadric}) {
    for (const char* clip : {"walk", "kick", "run"}) {
      const RunResult run = RunGarment(method, clip, 2.0, body);
      EXPECT_LE(run.max_depth, 0.002) << BodyCollisionMethodName(method) << ", " << clip;
      if (std::string(clip) == "walk") {
        EXPECT_LT(run.max_strain, 0.5) << BodyCollisionMethodName(method);
      }
      EXPECT_EQ(run.rolled_back, 0) << BodyCollisionMethodName(method) << ", " << clip;
    }
  }
}

// Fitting (mode A starts from it): on the standing avatar the skirt settles within the fit
// time without entering the body, with either method.
TEST(GarmentCollision, SkirtSettlesOnTheStandingAvatarWithEitherMethod) {
  for (BodyCollisionMethod method : {BodyCollisionMethod::kSuperquadric, BodyCollisionMethod::kMesh}) {
    const RunResult run = RunGarment(method, "stand", 1.0);
    EXPECT_LE(run.max_depth, 0.002) << BodyCollisionMethodName(method);
    EXPECT_LT(run.fitted_speed, 0.5) << BodyCollisionMethodName(method);
    EXPECT_LT(run.max_strain, 0.12) << BodyCollisionMethodName(method);
  }
}

// Self-collision on the moving avatar, not only on the napkin of self_collision_test: walking
// 4 s, the skirt (90 around) passes through itself without it (the positive control: it must,
// or this test shows nothing), and with it no edge of the skirt passes through one of its
// triangles in any sampled frame, and no particle goes deeper than the 2 mm. (At 64
// around it stopped passing through itself once contacts no longer pulled it onto the legs,
// walking and kicking alike: contact.h.)
TEST(GarmentCollision, SelfCollisionKeepsTheWalkingSkirtFromPassingThroughItself) {
  GarmentOptions off;
  off.count_crossings = true;
  off.resolution = 90;
  GarmentOptions on = off;
  on.self_collision = true;
  const RunResult without = RunGarment(BodyCollisionMethod::kMesh, "walk", 4.0, nullptr, off);
  const RunResult with = RunGarment(BodyCollisionMethod::kMesh, "walk", 4.0, nullptr, on);
  std::printf("edges through the skirt, most in a sampled frame / at the end: %d / %d without "
              "self-collision, %d / %d with it\n",
              without.most_crossing_edges, without.crossing_edges_at_end,
              with.most_crossing_edges, with.crossing_edges_at_end);
  EXPECT_GT(without.most_crossing_edges, 0);
  EXPECT_EQ(with.most_crossing_edges, 0);
  EXPECT_LE(with.max_depth, 0.002);
  EXPECT_EQ(with.rolled_back, 0);
}

// The dress, whose gathered folds the walking legs press together, with either method: the
// body backs the layer it touches, so the layer pressed on it stays out of the legs (before
// the body's holds and the proximity stage's cap, 22 mm deep with the superquadric method,
// docs/collision.md "On the avatar, mended"), and no edge passes through the dress.
TEST(GarmentCollision, SelfCollisionKeepsTheWalkingDressOutOfTheLegsWithEitherMethod) {
  GarmentOptions dress;
  dress.self_collision = true;
  dress.count_crossings = true;
  dress.pattern = "dress";
  for (BodyCollisionMethod method :
       {BodyCollisionMethod::kSuperquadric, BodyCollisionMethod::kMesh}) {
    const RunResult run = RunGarment(method, "walk", 4.0, nullptr, dress);
    EXPECT_LE(run.max_depth, 0.002) << BodyCollisionMethodName(method);
    EXPECT_EQ(run.most_crossing_edges, 0) << BodyCollisionMethodName(method);
    EXPECT_EQ(run.rolled_back, 0) << BodyCollisionMethodName(method);
  }
}

// At 90 around the layers of the walking cape and skirt press on each other at the knees,
// and self-collision's impulses pushed layers next to the skin into it for a frame (on the
// sim_core of c51c3d7: cape 6.63 mm, skirt 4.13 mm, superquadric method; the mesh method's
// runs stayed out, and take as long again, so only the superquadric method runs here). The
// body's correction after self-collision and ResolveMove over that move keep every layer out
// with no edge through the cloth (docs/collision.md, "The body once more").
TEST(GarmentCollision, SelfCollisionPushesNoLayerIntoTheWalkingBodyAtNinetyAround) {
  for (const char* pattern : {"cape", "skirt"}) {
    GarmentOptions options;
    options.self_collision = true;
    options.count_crossings = true;
    options.pattern = pattern;
    options.resolution = 90;
    const RunResult run =
        RunGarment(BodyCollisionMethod::kSuperquadric, "walk", 4.0, nullptr, options);
    EXPECT_LE(run.max_depth, 0.002) << pattern;
    EXPECT_EQ(run.most_crossing_edges, 0) << pattern;
    EXPECT_EQ(run.rolled_back, 0) << pattern;
  }
}

}  // namespace
}  // namespace costume::sim
