// The run measures against values set up by hand: a spring stretched by a known amount, a
// particle put a known depth inside the skin along the skin's own normal, a fold through the
// cloth; and the summary's statistics over frames of known values.
#include "sim_core/scene/garment_metrics.h"

#include <gtest/gtest.h>

#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/surface_geometry.h"
#include "tests/support/test_scenes.h"

namespace costume::sim {
namespace {

/// The built-in skirt on the standing built-in humanoid.
std::unique_ptr<Simulation> StandingSkirt() {
  SceneDescription scene;
  scene.name = "metrics";
  AvatarSpec avatar;
  avatar.avatar = MakeHumanoid();
  scene.avatar = avatar;
  GarmentSpec skirt;
  skirt.name = "skirt";
  skirt.pattern = "skirt";
  skirt.pattern_resolution = 32;
  skirt.material = "cotton";
  scene.garments.push_back(skirt);
  return Simulation::Build(scene);
}

/// The first structural spring of `model` with no pinned end.
const Spring& FreeStructuralSpring(const ClothModel& model) {
  for (const Spring& s : model.springs()) {
    if (s.kind == SpringKind::kStructural && !model.is_pinned()[s.a] && !model.is_pinned()[s.b]) {
      return s;
    }
  }
  throw std::logic_error("no free structural spring");
}

TEST(GarmentMetrics, MeasuresAStretchedSpringAndADepthInsideTheSkin) {
  auto simulation = StandingSkirt();
  GarmentMetrics metrics(*simulation);
  FrameReport report;
  report.wall_ms = 2.0;
  metrics.AddFrame(*simulation, report);  // at rest: nothing stretched, nothing inside
  EXPECT_NEAR(metrics.frame_max_strain().back(), 0.0, 1e-9);
  EXPECT_EQ(metrics.frame_penetration().back(), 0.0);

  // Stretch one free spring by 40 % along itself.
  ClothState& state = simulation->mutable_state();
  const Spring& spring = FreeStructuralSpring(simulation->model());
  const Eigen::RowVector3d d = state.positions.row(spring.b) - state.positions.row(spring.a);
  state.positions.row(spring.b) = state.positions.row(spring.a) + 1.4 * d;
  // And put a free particle 5 mm inside the skin: below the skin vertex nearest to it,
  // along that vertex's outward normal (the vertex's own triangles, computed here).
  const Avatar& body = simulation->avatar()->avatar();
  const Points& skin = simulation->avatar()->vertices();
  int vertex = 0;
  for (int v = 1; v < skin.rows(); ++v) {
    if (skin(v, 1) < 0.8 && skin(v, 1) > 0.7 && skin(v, 2) > skin(vertex, 2)) vertex = v;
  }  // the front of the belly, where the skin is smooth
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3i& t : body.triangles()) {
    if (t[0] != vertex && t[1] != vertex && t[2] != vertex) continue;
    const Eigen::Vector3d a = skin.row(t[0]), b = skin.row(t[1]), c = skin.row(t[2]);
    normal += (b - a).cross(c - a);
  }
  normal.normalize();
  int inside = simulation->model().num_particles() - 1;  // on the hem: never pinned
  if (inside == spring.a || inside == spring.b) --inside;
  ASSERT_FALSE(simulation->model().is_pinned()[inside]);
  state.positions.row(inside) = skin.row(vertex) - 0.005 * normal.transpose();
  report.wall_ms = 4.0;
  metrics.AddFrame(*simulation, report);
  EXPECT_NEAR(metrics.frame_penetration().back(), 0.005, 0.0005);
  double longest = 0.0;  // the oracle: every structural spring's strain, here
  for (const Spring& s : simulation->model().springs()) {
    if (s.kind != SpringKind::kStructural) continue;
    longest = std::max(
        longest, (state.positions.row(s.b) - state.positions.row(s.a)).norm() / s.rest_length - 1);
  }
  EXPECT_NEAR(metrics.frame_max_strain().back(), longest, 1e-12);
  EXPECT_GE(longest, 0.4 - 1e-9);

  const RunSummary summary = metrics.Summary();
  EXPECT_EQ(summary.frames, 2);
  EXPECT_EQ(summary.particles, simulation->model().num_particles());
  EXPECT_NEAR(summary.max_strain, longest, 1e-12);
  EXPECT_NEAR(summary.max_strain_p99, longest, 1e-12);  // nearest rank of 2: the larger
  EXPECT_NEAR(*summary.penetration_max_mm, 5.0, 0.5);
  EXPECT_DOUBLE_EQ(summary.ms_per_frame_median, 2.0);  // nearest rank: the first of two
  EXPECT_DOUBLE_EQ(summary.ms_per_frame_p95, 4.0);
  EXPECT_EQ(summary.nan, 0);
}

TEST(GarmentMetrics, CountsEdgesThroughTheClothAndSaysWhyNoDepthWithoutAnAvatar) {
  auto simulation = Simulation::Build(test::HangScene(9));
  GarmentMetrics metrics(*simulation);
  // Crumpled at random: the count is CountCrossingEdges' (tested against a brute force in
  // self_collision_test).
  Points& x = simulation->mutable_state().positions;
  std::srand(7);
  for (Eigen::Index i = 0; i < x.rows(); ++i) x(i, 1) += 0.2 * (std::rand() / double(RAND_MAX));
  metrics.AddFrame(*simulation, FrameReport{});
  const RunSummary summary = metrics.Summary();
  ASSERT_TRUE(summary.crossing_edges_max.has_value());
  EXPECT_EQ(*summary.crossing_edges_max, CountCrossingEdges(simulation->model(), x));
  EXPECT_FALSE(summary.penetration_max_mm.has_value());
  EXPECT_EQ(summary.penetration_unmeasured, "the scene has no avatar");
}

}  // namespace
}  // namespace costume::sim
