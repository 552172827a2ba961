// A garment on the walking and kicking avatar (paper §4, §6; mode A): the skirt is fitted to
// the built-in humanoid and follows its clip; the oracle is the true skinned mesh (signed
// distance to the skin, MeshDistance), not the collider's own proxy.
#include <gtest/gtest.h>

#include <cstdio>

#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"

namespace costume::sim {
namespace {

struct RunResult {
  double max_depth = 0.0;        // deepest particle inside the skin over the run [m]
  double max_strain = 0.0;       // after fitting [-]
  double fitted_speed = 0.0;     // fastest particle when fitting ends [m/s]
  int rolled_back = 0;
};

RunResult RunSkirt(BodyCollisionMethod method, const std::string& clip, double seconds) {
  static const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  SceneDescription scene;
  scene.source = "garment_collision_test";
  scene.solver.method = SolverMethod::kMultigrid;
  AvatarSpec avatar;
  avatar.avatar = humanoid;
  if (clip != "none") {
    avatar.clip = std::make_shared<const Clip>(MakeBuiltInClip(clip, humanoid->shared_skeleton()));
  }
  avatar.collision = method;
  scene.avatar = avatar;
  scene.duration = avatar.motion.fit_time + seconds;
  GarmentSpec skirt;
  skirt.name = "skirt";
  skirt.pattern = "skirt";
  scene.garments.push_back(skirt);

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
  }
  std::printf("%s, %s: deepest particle %.2f mm inside the skin, max strain %.1f %%, speed after fitting %.3f m/s\n",
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
    const RunResult run = RunSkirt(BodyCollisionMethod::kMesh, clip, 2.0);
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
    const RunResult run = RunSkirt(BodyCollisionMethod::kSuperquadric, clip, 2.0);
    EXPECT_LE(run.max_depth, 0.002) << clip;
    EXPECT_LT(run.max_strain, std::string(clip) == "walk" ? 0.4 : 1.0) << clip;
    EXPECT_EQ(run.rolled_back, 0) << clip;
  }
}

// Fitting (mode A starts from it): on the standing avatar the skirt settles within the fit
// time without entering the body, with either method.
TEST(GarmentCollision, SkirtSettlesOnTheStandingAvatarWithEitherMethod) {
  for (BodyCollisionMethod method : {BodyCollisionMethod::kSuperquadric, BodyCollisionMethod::kMesh}) {
    const RunResult run = RunSkirt(method, "stand", 1.0);
    EXPECT_LE(run.max_depth, 0.002) << BodyCollisionMethodName(method);
    EXPECT_LT(run.fitted_speed, 0.5) << BodyCollisionMethodName(method);
    EXPECT_LT(run.max_strain, 0.12) << BodyCollisionMethodName(method);
  }
}

}  // namespace
}  // namespace costume::sim
