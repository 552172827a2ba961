// A run of a garment in a measured fabric on a moving body gives the same state to the bit
// run after run: the strain limit's sweeps, the planes and the tethers go in a fixed order.
#include <gtest/gtest.h>

#include "assets/scene_file.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim {
namespace {

TEST(GarmentRuns, AreBitIdenticalRunAfterRun) {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  scene.duration = 1.5;  // the fit and a second of the walk
  const auto run = [&] {
    auto simulation = Simulation::Build(scene);
    for (int f = 0; f < simulation->num_frames(); ++f) simulation->AdvanceFrame();
    return simulation->state();
  };
  const ClothState first = run(), second = run();
  EXPECT_TRUE((first.positions.array() == second.positions.array()).all());
  EXPECT_TRUE((first.velocities.array() == second.velocities.array()).all());
}

}  // namespace
}  // namespace costume::sim
