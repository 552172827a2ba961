// Editing the cloth (mode B, paper §5): the Gaussian grab, the feedback force, and the two
// edit cases of DESIGN.md — released cloth returns to rest (case 1); after "eliminate stretch
// energy" it stays where it was left (case 2); undo brings case 1 back.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "sim_core/scene/grab.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"
#include "tests/support/test_scenes.h"

namespace costume::sim {
namespace {

TEST(Grab, WeightIsOneAtTheCentreAndEToTheMinusTwoAtTheRadius) {
  Grab grab;
  grab.centre = Eigen::Vector3d(0.1, 0.2, 0.3);
  grab.radius = 0.08;
  EXPECT_DOUBLE_EQ(GrabWeight(grab, grab.centre), 1.0);
  EXPECT_NEAR(GrabWeight(grab, grab.centre + Eigen::Vector3d(0, 0.08, 0)), std::exp(-2.0), 1e-15);
  // s = (r/2)² = 1.6e-3 m²: at distance sqrt(s) = 4 cm, g = e^(−1/2).
  EXPECT_NEAR(GrabWeight(grab, grab.centre + Eigen::Vector3d(0.04, 0, 0)), std::exp(-0.5), 1e-15);
}

TEST(Grab, AppliesTheWeightedForceInsideTheSphereOnly) {
  Points x(3, 3);
  x << 0, 0, 0,  0.03, 0, 0,  0.2, 0, 0;
  Grab grab;
  grab.radius = 0.1;
  grab.force = Eigen::Vector3d(0, -2, 0);
  Points applied;
  std::vector<int> selected;
  SelectGrabbed(grab, x, selected);
  ApplyGrab(grab, x, selected, applied);
  EXPECT_EQ(selected, (std::vector<int>{0, 1}));
  EXPECT_NEAR(applied(0, 1), -2.0, 1e-15);
  EXPECT_NEAR(applied(1, 1), -2.0 * std::exp(-0.0009 / (2 * 0.0025)), 1e-15);
  EXPECT_EQ(applied.row(2).norm(), 0.0);
}

// Three particles in a row joined by two springs (k = 10 N/m, rest 0.1 m), the middle one
// selected: the feedback is the two spring forces on it (what the holding hand feels), by
// Hooke's law by hand.
TEST(Grab, FeedbackIsTheSpringForcesOnTheSelectedParticles) {
  ClothModelData data;
  data.rest_positions.resize(3, 3);
  data.rest_positions << 0, 0, 0,  0.1, 0, 0,  0.2, 0, 0;
  data.masses = Eigen::VectorXd::Constant(3, 0.01);
  data.areas = Eigen::VectorXd::Zero(3);
  data.springs = {{0, 1, SpringKind::kStructural, 10.0, 0.0, 0.1},
                  {1, 2, SpringKind::kStructural, 10.0, 0.0, 0.1}};
  const auto model = ClothModel::Create(data);
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 1) = 0.05;  // middle particle lifted 5 cm
  std::vector<char> scratch;
  const Eigen::Vector3d feedback = GrabFeedback(*model, state, {1}, scratch);
  // Each spring: length L = sqrt(0.1² + 0.05²), force on the middle particle
  // k (L − 0.1) towards its neighbour; the x parts cancel, the y parts add.
  const double length = std::hypot(0.1, 0.05);
  const double pull_y = 2 * 10.0 * (length - 0.1) * (0.05 / length);  // downwards
  EXPECT_NEAR(feedback.x(), 0.0, 1e-12);
  EXPECT_NEAR(feedback.y(), -pull_y, 1e-12);  // the springs pull the lifted particle down
  EXPECT_TRUE(GrabFeedback(*model, ClothState::AtRest(*model), {1}, scratch).isZero(1e-15));
}

/// Frames to settle after building and after letting go (10 s: the soft sheet swings slowly).
constexpr int kSettleFrames = 600;

/// A soft hanging sheet (so a grab of a newton stretches it by centimetres), settled.
std::unique_ptr<Simulation> SettledSheet(SolverMethod method = SolverMethod::kPcg) {
  Material soft;
  soft.name = "soft";
  soft.stretch_stiffness = soft.shear_stiffness = 20.0;  // N/m
  soft.bending_rigidity = 1e-6;
  SceneDescription scene = test::HangScene(17, soft);
  scene.solver.strain_limit = 0.0;  // the stretch is the point here
  scene.solver.tolerance = 1e-4;
  scene.solver.method = method;
  auto simulation = Simulation::Build(scene);
  for (int f = 0; f < kSettleFrames; ++f) simulation->AdvanceFrame();
  return simulation;
}

/// Mean height of the free bottom edge (row 16) [m].
double BottomHeight(const Simulation& simulation) {
  double sum = 0.0;
  for (int j = 0; j < 17; ++j) sum += simulation.state().positions(16 * 17 + j, 1);
  return sum / 17;
}

/// Pulls the middle of the bottom edge down with 0.25 N for 1.5 s; returns the grab.
Grab PullDown(Simulation& simulation) {
  Grab grab;
  grab.centre = simulation.state().positions.row(16 * 17 + 8).transpose();
  grab.radius = 0.3;
  grab.force = Eigen::Vector3d(0, -0.25, 0);
  EXPECT_TRUE(simulation.SetGrab(grab));
  for (int f = 0; f < 90; ++f) {
    grab.centre = simulation.state().positions.row(16 * 17 + 8).transpose();
    simulation.SetGrab(grab);  // the sphere follows the grabbed point, as a device would
    simulation.AdvanceFrame();
  }
  return grab;
}

TEST(ClothEditing, ReleasedClothReturnsToRestButStaysWhereLeftAfterEliminatingStretch) {
  // Case 1: the force only deforms.
  auto sheet = SettledSheet();
  const double rest = BottomHeight(*sheet);
  PullDown(*sheet);
  const double pulled = BottomHeight(*sheet);
  EXPECT_GT(sheet->grab_feedback().y(), 0.0);  // the cloth pulls the device back up
  std::printf("feedback %.3f N up\n", sheet->grab_feedback().y());
  sheet->ReleaseGrab();
  for (int f = 0; f < kSettleFrames; ++f) sheet->AdvanceFrame();
  const double returned = BottomHeight(*sheet);
  std::printf("case 1: bottom edge at rest %.4f m, pulled %.4f m, released %.4f m\n", rest,
              pulled, returned);
  EXPECT_LT(pulled, rest - 0.05);             // the grab stretched it by centimetres
  EXPECT_NEAR(returned, rest, 0.1 * (rest - pulled));  // and it came back

  // Case 2: stretch made permanent while held.
  auto edited = SettledSheet();
  PullDown(*edited);
  const double left_at = BottomHeight(*edited);
  EXPECT_GT(edited->EliminateStretchEnergy(Eigen::Vector3d(0, -0.5, -0.5), 2.0), 0);
  edited->ReleaseGrab();
  for (int f = 0; f < kSettleFrames; ++f) edited->AdvanceFrame();
  const double stayed = BottomHeight(*edited);
  std::printf("case 2: left at %.4f m, after release %.4f m\n", left_at, stayed);
  EXPECT_NEAR(stayed, left_at, 0.2 * (rest - left_at));

  // Undo: the original rest lengths, so it returns to the case-1 rest.
  EXPECT_TRUE(edited->UndoEdit());
  EXPECT_FALSE(edited->UndoEdit());
  for (int f = 0; f < kSettleFrames; ++f) edited->AdvanceFrame();
  std::printf("undone: %.4f m\n", BottomHeight(*edited));
  EXPECT_NEAR(BottomHeight(*edited), rest, 0.1 * (rest - left_at));
}

// The same edit with the multigrid solver: the pyramid's coarse levels take the new rest
// lengths for the region (and the old ones back on undo), or the preconditioner would pull
// towards the old shape and the solve would need far more iterations.
TEST(ClothEditing, MultigridFollowsTheEditAndItsUndo) {
  auto edited = SettledSheet(SolverMethod::kMultigrid);
  const double rest = BottomHeight(*edited);
  PullDown(*edited);
  const double left_at = BottomHeight(*edited);
  ASSERT_GT(edited->EliminateStretchEnergy(Eigen::Vector3d(0, -0.5, -0.5), 2.0), 0);
  edited->ReleaseGrab();
  int iterations = 0;
  for (int f = 0; f < kSettleFrames; ++f) iterations += edited->AdvanceFrame().iterations;
  std::printf("multigrid: left at %.4f m, after release %.4f m, %.1f iterations per frame\n",
              left_at, BottomHeight(*edited), double(iterations) / kSettleFrames);
  EXPECT_NEAR(BottomHeight(*edited), left_at, 0.2 * (rest - left_at));
  ASSERT_TRUE(edited->UndoEdit());
  for (int f = 0; f < kSettleFrames; ++f) edited->AdvanceFrame();
  EXPECT_NEAR(BottomHeight(*edited), rest, 0.1 * (rest - left_at));
}

// The position coupling (grab.h): the grabbed particles follow the sphere through implicit
// springs, stable even at a stiffness that an explicit force could not survive on this light
// cloth (h²·k·g/m ≈ 10⁵ per particle at 1e5 N/m), and the grabbed middle of the bottom edge
// ends within a few millimetres of where the sphere took it.
TEST(ClothEditing, CouplingGrabFollowsTheSphereStablyAtAnyStiffness) {
  for (double stiffness : {1e3, 1e5}) {
    auto sheet = SettledSheet();
    const int middle = 16 * 17 + 8;
    const Eigen::Vector3d start = sheet->state().positions.row(middle).transpose();
    Grab grab;
    grab.centre = start;
    grab.radius = 0.1;
    grab.coupling_stiffness = stiffness;
    ASSERT_TRUE(sheet->SetGrab(grab));
    for (int f = 0; f < 120; ++f) {  // 10 cm along +z over 1 s, then held 1 s
      grab.centre = start + Eigen::Vector3d(0, 0, 0.1 * std::min(1.0, f / 60.0));
      sheet->SetGrab(grab);
      EXPECT_EQ(sheet->AdvanceFrame().rolled_back_steps, 0);
    }
    const Eigen::Vector3d reached = sheet->state().positions.row(middle).transpose();
    std::printf("coupling %.0e N/m: grabbed particle moved %.4f m along z (sphere 0.1 m)\n",
                stiffness, reached.z() - start.z());
    EXPECT_TRUE(sheet->state().positions.allFinite());
    EXPECT_NEAR(reached.z() - start.z(), 0.1, stiffness >= 1e5 ? 0.005 : 0.03);
  }
}

TEST(ClothEditing, RefusesBadGrabsAndEmptyEdits) {
  auto sheet = SettledSheet();
  Grab bad;
  bad.radius = -1.0;
  EXPECT_FALSE(sheet->SetGrab(bad));
  bad.radius = 0.1;
  bad.force = Eigen::Vector3d(std::nan(""), 0, 0);
  EXPECT_FALSE(sheet->SetGrab(bad));
  EXPECT_FALSE(sheet->grabbing());
  EXPECT_EQ(sheet->EliminateStretchEnergy(Eigen::Vector3d(5, 5, 5), 0.1), 0);
  EXPECT_EQ(sheet->num_undoable_edits(), 0);
}

}  // namespace
}  // namespace costume::sim
