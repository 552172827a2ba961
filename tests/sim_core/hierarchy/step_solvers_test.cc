// The hierarchical step and multigrid PCG solve the same system as CHOLMOD: at a tight
// tolerance they follow the direct solver's trajectory, with pins and contacts.
#include "sim_core/hierarchy/step_solvers.h"

#include <gtest/gtest.h>

#include "sim_core/scene/simulation.h"
#include "tests/support/count_mallocs.h"
#include "tests/support/test_scenes.h"

namespace costume::sim {
namespace {

double MaxDeviationFromDirect(SceneDescription scene, SolverMethod method, int frames) {
  scene.solver.tolerance = 1e-10;
  scene.solver.max_iterations = 100000;
  scene.solver.method = SolverMethod::kDirect;
  auto direct = Simulation::Build(scene);
  scene.solver.method = method;
  auto other = Simulation::Build(scene);
  EXPECT_GT(other->pyramid()->num_levels(), 2);
  for (int f = 0; f < frames; ++f) {
    direct->AdvanceFrame();
    const FrameReport report = other->AdvanceFrame();
    EXPECT_TRUE(report.converged) << SolverMethodName(method) << " frame " << f;
  }
  return (direct->state().positions - other->state().positions).cwiseAbs().maxCoeff();
}

// The multigrid is left out: its coarsest level's CHOLMOD factorisation allocates its
// numeric workspace on every step (10 allocations a factorisation, measured; the solves with
// that factor allocate nothing).
TEST(StepSolvers, AFrameOnTwoThreadsAllocatesNothingAfterTheFirst) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kHierarchical}) {
    SceneDescription scene = test::HangScene(33);  // 1,089 particles: five chunks a loop
    scene.solver.method = method;
    scene.solver.threads = 2;
    auto simulation = Simulation::Build(scene);
    simulation->AdvanceFrame();
    g_num_allocations = 0;
    g_count_allocations = true;
    for (int f = 0; f < 5; ++f) simulation->AdvanceFrame();
    g_count_allocations = false;
    EXPECT_EQ(g_num_allocations, 0) << SolverMethodName(method);
  }
}

TEST(StepSolvers, HierarchicalFollowsTheDirectSolverOnTheHangingCloth) {
  EXPECT_LT(MaxDeviationFromDirect(test::HangScene(17), SolverMethod::kHierarchical, 30), 1e-6);
}

TEST(StepSolvers, MultigridFollowsTheDirectSolverOnTheHangingCloth) {
  EXPECT_LT(MaxDeviationFromDirect(test::HangScene(17), SolverMethod::kMultigrid, 30), 1e-6);
}

TEST(StepSolvers, BothFollowTheDirectSolverThroughContacts) {
  for (SolverMethod method : {SolverMethod::kHierarchical, SolverMethod::kMultigrid}) {
    EXPECT_LT(MaxDeviationFromDirect(test::DrapeScene(17), method, 40), 1e-5)
        << SolverMethodName(method);
  }
}

TEST(StepSolvers, MultigridNeedsFarFewerIterationsThanFlatPcg) {
  SceneDescription scene = test::HangScene(33);
  scene.solver.tolerance = 1e-6;
  scene.solver.max_iterations = 100000;
  auto flat = Simulation::Build(scene);
  scene.solver.method = SolverMethod::kMultigrid;
  auto multigrid = Simulation::Build(scene);
  int flat_iterations = 0, multigrid_iterations = 0;
  for (int f = 0; f < 20; ++f) {
    flat_iterations += flat->AdvanceFrame().iterations;
    multigrid_iterations += multigrid->AdvanceFrame().iterations;
  }
  EXPECT_LT(multigrid_iterations * 5, flat_iterations);
}

}  // namespace
}  // namespace costume::sim
