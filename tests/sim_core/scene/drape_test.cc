// The drape scene: a sheet dropped onto an analytic sphere never enters it, rests on top and
// hangs down around it.
#include <gtest/gtest.h>

#include "sim_core/scene/simulation.h"
#include "tests/support/test_scenes.h"

namespace costume::sim {
namespace {

double MinDistance(const Points& x, const Eigen::Vector3d& centre) {
  return (x.rowwise() - centre.transpose()).rowwise().norm().minCoeff();
}

TEST(Drape, NoParticleEverEntersTheSphere) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kDirect}) {
    SceneDescription scene = test::DrapeScene(25);
    scene.solver.method = method;
    auto sim = Simulation::Build(scene);
    const SphereObstacleSpec& sphere = scene.spheres[0];
    double worst_penetration_in_solve = 0.0;
    for (int f = 0; f < 120; ++f) {
      const FrameReport report = sim->AdvanceFrame();
      worst_penetration_in_solve = std::max(worst_penetration_in_solve, report.max_penetration);
      // After every frame: outside the sphere and its thickness shell.
      ASSERT_GE(MinDistance(sim->state().positions, sphere.center),
                sphere.radius + sphere.thickness - 1e-9)
          << "frame " << f;
    }
    // Even before the position correction, the solve never reaches the sphere itself: what
    // enters the thickness shell (a contact released because it pulled, falling back within
    // one step) stays inside the 5 mm the thickness reserves.
    EXPECT_LT(worst_penetration_in_solve, sphere.thickness) << SolverMethodName(method);
    // The sheet rests on the sphere (its lowest-centre particle touches the shell top)...
    const int centre = (25 * 25) / 2;
    EXPECT_NEAR(sim->state().positions(centre, 1), sphere.radius + sphere.thickness, 2e-3);
    // ...and its corners hang below the sphere's equator.
    EXPECT_LT(sim->state().positions(0, 1), 0.0);
  }
}

}  // namespace
}  // namespace costume::sim
