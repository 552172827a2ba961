// The built-in scenes are what a fresh machine runs (scripts/demo.sh): with their default
// solver settings every step must reach its tolerance within the iteration cap and stay
// finite, or the simulation server would warn in every status (SimServer's solver warnings)
// and the cloth would lag its physics.
#include <gtest/gtest.h>

#include "assets/scene_file.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim {
namespace {

TEST(BuiltInDefaults, EveryStepConvergesAndStaysFiniteForTwoSeconds) {
  for (const std::string& name : assets::BuiltInSceneNames()) {
    SCOPED_TRACE(name);
    auto simulation = Simulation::Build(assets::LoadBuiltInScene(name));
    int unconverged = 0, rolled_back = 0;
    for (int f = 0; f < 120; ++f) {
      const FrameReport report = simulation->AdvanceFrame();
      unconverged += report.converged ? 0 : 1;
      rolled_back += report.rolled_back_steps;
    }
    EXPECT_EQ(unconverged, 0);
    EXPECT_EQ(rolled_back, 0);
    EXPECT_TRUE(simulation->state().positions.allFinite());
  }
}

}  // namespace
}  // namespace costume::sim
