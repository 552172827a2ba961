// The quincunx pyramid: which particles each level keeps, what it conserves, the dynamic
// equivalence of its coarse models (one implicit step of level l+1 against level l's step
// restricted), and the region update after an edit.
#include "sim_core/hierarchy/quincunx_pyramid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/solver/implicit_stepper.h"
#include "tests/support/smooth_state.h"

namespace costume::sim {
namespace {

std::shared_ptr<const ClothModel> Sheet(int n, const Material& material = {},
                                        std::vector<int> pinned = {}) {
  LatticePanel panel;
  panel.cols = panel.rows = n;
  ClothModelData data = BuildLatticePanel(panel, material, "sheet");
  data.pinned = std::move(pinned);
  return ClothModel::Create(data);
}

TEST(QuincunxPyramid, KeepsEvenParticlesThenBothEvenCoordinates) {
  const int n = 17;
  QuincunxPyramid pyramid(Sheet(n), 3);
  ASSERT_EQ(pyramid.num_levels(), 3);
  // Level 1: (i + j) even, (n² + 1) / 2 of them; level 2: i and j both even.
  EXPECT_EQ(pyramid.level(1).model->num_particles(), (n * n + 1) / 2);
  for (int g : pyramid.level(1).level0_index) EXPECT_EQ((g % n + g / n) % 2, 0);
  EXPECT_EQ(pyramid.level(2).model->num_particles(), ((n + 1) / 2) * ((n + 1) / 2));
  for (int g : pyramid.level(2).level0_index) {
    EXPECT_EQ(g % n % 2, 0);
    EXPECT_EQ(g / n % 2, 0);
  }
}

TEST(QuincunxPyramid, BuildsAsManyLevelsAsTheLatticeAllows) {
  // 17×17 → 145 → 81 → 41 → 25 → (13 < 25: stop): five levels.
  EXPECT_EQ(QuincunxPyramid::MaxLevels(17, 17), 5);
  EXPECT_EQ(QuincunxPyramid(Sheet(17), 0).num_levels(), 5);
}

TEST(QuincunxPyramid, ConservesMassAndKeepsCornerPinsOnEveryLevel) {
  const int n = 33;
  QuincunxPyramid pyramid(Sheet(n, Material{}, {0, n - 1}), 0);
  ASSERT_GE(pyramid.num_levels(), 6);
  for (int l = 0; l < pyramid.num_levels(); ++l) {
    const ClothModel& model = *pyramid.level(l).model;
    EXPECT_NEAR(model.total_mass(), 0.1, 1e-12) << "level " << l;
    std::set<int> pinned_level0;
    for (int p : model.pinned()) pinned_level0.insert(pyramid.level(l).level0_index[p]);
    EXPECT_EQ(pinned_level0, (std::set<int>{0, n - 1})) << "level " << l;
  }
}

TEST(QuincunxPyramid, ProlongationReproducesConstantsAndRestrictionIsItsTranspose) {
  QuincunxPyramid pyramid(Sheet(9), 2);
  const int nc = pyramid.level(1).model->num_particles();
  const int nf = pyramid.level(0).model->num_particles();
  Eigen::VectorXd coarse = Eigen::VectorXd::Zero(3 * nc), fine(3 * nf);
  for (int c = 0; c < nc; ++c) coarse.segment<3>(3 * c) = Eigen::Vector3d(1, -2, 3);
  pyramid.Prolongate(1, coarse, fine);
  for (int f = 0; f < nf; ++f) EXPECT_LT((fine.segment<3>(3 * f) - Eigen::Vector3d(1, -2, 3)).norm(), 1e-12);
  // ⟨P c, f⟩ = ⟨c, Pᵀ f⟩ for random vectors.
  coarse.setRandom();
  Eigen::VectorXd other = Eigen::VectorXd::Random(3 * nf), restricted(3 * nc);
  pyramid.Prolongate(1, coarse, fine);
  pyramid.Restrict(1, other, restricted);
  EXPECT_NEAR(fine.dot(other), coarse.dot(restricted), 1e-10);
}

using test::SmoothState;

/// Δv of one implicit step of `model` from `state` (CHOLMOD, so no solver error enters).
Eigen::VectorXd StepChange(std::shared_ptr<const ClothModel> model, const ClothState& state,
                           double h) {
  StepperSettings settings;
  settings.method = SolverMethod::kDirect;
  settings.external.gravity.setZero();
  settings.external.air_drag = false;
  ImplicitStepper stepper(model, settings);
  ClothState after = state;
  stepper.Step(after, h, {});
  const Points dv = after.velocities - state.velocities;
  return Eigen::Map<const Eigen::VectorXd>(dv.data(), dv.size());
}

/// The naive coarse model: level l+1's particles and springs with level 0's constants per
/// kind and the fine particles' own masses.
std::shared_ptr<const ClothModel> NaiveCopy(const QuincunxPyramid& pyramid, int l) {
  ClothModelData data = pyramid.level(l).model->data();
  const ClothModel& fine = *pyramid.level(0).model;
  for (Eigen::Index p = 0; p < data.masses.size(); ++p) {
    data.masses[p] = fine.masses()[pyramid.level(l).level0_index[p]];
  }
  for (Spring& s : data.springs) {
    s.stiffness = pyramid.constants(0).stiffness[static_cast<int>(s.kind)];
    s.damping = pyramid.constants(0).damping[static_cast<int>(s.kind)];
  }
  return ClothModel::Create(data);
}

/// Relative difference between level l's step and the finer level's step restricted to
/// level l's particles (both from the same smooth state).
double StepMismatch(const QuincunxPyramid& pyramid, int l, std::shared_ptr<const ClothModel> coarse,
                    double h) {
  const PyramidLevel& fine_level = pyramid.level(l - 1);
  const ClothState fine_state = SmoothState(*fine_level.model);
  const Eigen::VectorXd fine_dv = StepChange(fine_level.model, fine_state, h);
  const ClothState coarse_state = SmoothState(*coarse);
  const Eigen::VectorXd coarse_dv = StepChange(coarse, coarse_state, h);
  // Restriction to kept particles is a gather.
  Eigen::VectorXd restricted(coarse_dv.size());
  for (std::size_t f = 0; f < pyramid.level(l).kept.size(); ++f) {
    const int c = pyramid.level(l).kept[f];
    if (c >= 0) restricted.segment<3>(3 * c) = fine_dv.segment<3>(3 * f);
  }
  return (coarse_dv - restricted).norm() / restricted.norm();
}

// Where mass and stiffness both matter (h²k/m of the sheet's smooth modes near 1), the
// dynamic-equivalent level reproduces the finer level's next step; the naive model, with
// the fine constants and masses, does not (docs/pyramid.md states the bound).
TEST(QuincunxPyramid, CoarseStepMatchesRestrictedFineStepWhereTheNaiveModelFails) {
  Material material;
  material.stretch_stiffness = material.shear_stiffness = 100.0;  // N/m
  material.bending_rigidity = 1e-6;
  QuincunxPyramid pyramid(Sheet(33, material), 3);
  const double h = 1.0 / 120.0;
  for (int l = 1; l <= 2; ++l) {
    const double equivalent = StepMismatch(pyramid, l, pyramid.level(l).model, h);
    const double naive = StepMismatch(pyramid, l, NaiveCopy(pyramid, l), h);
    std::printf("level %d: step mismatch %.3f (dynamic equivalent) vs %.3f (naive)\n", l,
                equivalent, naive);
    EXPECT_LT(equivalent, 0.02) << "level " << l;
    EXPECT_GT(naive, 0.10) << "level " << l;
  }
}

TEST(QuincunxPyramid, UpdateRegionSetsCoarseRestLengthsInsideTheRegionOnly) {
  const int n = 17;
  auto level0 = Sheet(n);
  QuincunxPyramid pyramid(level0, 3);
  // Stretch the sheet 5 % along x and make that the rest shape inside a disc (§5.3).
  Points positions = level0->rest_positions();
  positions.col(0) *= 1.05;
  std::vector<int> region;
  for (int g = 0; g < level0->num_particles(); ++g) {
    if (level0->rest_positions().row(g).norm() < 0.3) region.push_back(g);
  }
  std::set<int> in_region(region.begin(), region.end());
  Eigen::VectorXd rest(level0->num_springs());
  for (int k = 0; k < level0->num_springs(); ++k) {
    const Spring& s = level0->springs()[k];
    rest[k] = in_region.count(s.a) && in_region.count(s.b)
                  ? (positions.row(s.b) - positions.row(s.a)).norm()
                  : s.rest_length;
  }
  const auto before = pyramid.level(2).model;
  pyramid.UpdateRegion(level0->WithRestLengths(rest), positions, region);
  const PyramidLevel& level = pyramid.level(2);
  ASSERT_EQ(level.model->num_springs(), before->num_springs());  // same topology
  int changed = 0;
  for (int k = 0; k < level.model->num_springs(); ++k) {
    const Spring& s = level.model->springs()[k];
    const int ga = level.level0_index[s.a], gb = level.level0_index[s.b];
    if (in_region.count(ga) && in_region.count(gb)) {
      EXPECT_NEAR(s.rest_length, (positions.row(gb) - positions.row(ga)).norm(), 1e-12);
      ++changed;
    } else {
      EXPECT_EQ(s.rest_length, before->springs()[k].rest_length);
    }
  }
  EXPECT_GT(changed, 10);
}

}  // namespace
}  // namespace costume::sim
