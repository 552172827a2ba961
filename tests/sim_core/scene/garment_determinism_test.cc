// A run of a garment in a measured fabric on a moving body gives the same state to the bit
// run after run: the strain limit's sweeps, the planes and the tethers go in a fixed order;
// and the same bits on one thread and on two (the solver's loops sum in fixed chunks).
#include <gtest/gtest.h>

#include "assets/scene_file.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim {
namespace {

ClothState RunGarment(int threads, SolverMethod method) {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  scene.duration = 1.5;  // the fit and a second of the walk
  scene.solver.threads = threads;
  scene.solver.method = method;
  auto simulation = Simulation::Build(scene);
  for (int f = 0; f < simulation->num_frames(); ++f) simulation->AdvanceFrame();
  return simulation->state();
}

bool SameBits(const ClothState& a, const ClothState& b) {
  return (a.positions.array() == b.positions.array()).all() &&
         (a.velocities.array() == b.velocities.array()).all();
}

TEST(GarmentRuns, AreBitIdenticalRunAfterRun) {
  SceneDescription scene = assets::LoadBuiltInScene("garment");
  scene.duration = 1.5;  // the fit and a second of the walk
  scene.solver.threads = 1;
  const auto run = [&] {
    auto simulation = Simulation::Build(scene);
    for (int f = 0; f < simulation->num_frames(); ++f) simulation->AdvanceFrame();
    return simulation->state();
  };
  const ClothState first = run(), second = run();
  EXPECT_TRUE((first.positions.array() == second.positions.array()).all());
  EXPECT_TRUE((first.velocities.array() == second.velocities.array()).all());
}

TEST(GarmentRuns, AreTheSameBitsOnOneAndOnTwoThreads) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kMultigrid}) {
    const ClothState one = RunGarment(1, method);
    EXPECT_TRUE(SameBits(one, RunGarment(2, method))) << SolverMethodName(method);
  }
}

}  // namespace
}  // namespace costume::sim
