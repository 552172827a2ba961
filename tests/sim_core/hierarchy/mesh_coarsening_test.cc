// Independent-set coarsening of general meshes: on a lattice it must reproduce quincunx
// sampling and the lattice's dynamic-equivalent constants (derived by hand in
// docs/pyramid.md); on an irregular triangle mesh one implicit step of the coarse level must
// match the fine step restricted to the coarse particles where the naive model does not; on a
// quad mesh the kept set and multigrid's convergence must not depend on its numbering.
#include "sim_core/hierarchy/mesh_coarsening.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <random>

#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/cloth/mesh_cloth.h"
#include "sim_core/common/input_error.h"
#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/hierarchy/step_solvers.h"
#include "sim_core/solver/implicit_stepper.h"
#include "tests/support/one_step.h"
#include "tests/support/smooth_state.h"

namespace costume::sim {
namespace {

Material Stiff() {
  Material material;
  material.stretch_stiffness = material.shear_stiffness = 100.0;  // N/m
  material.bending_rigidity = 1e-6;
  return material;
}

Material StiffCotton() {
  Material material;
  material.stretch_stiffness = material.shear_stiffness = 1000.0;  // N/m
  return material;
}

/// A lattice panel with its lattice marked unknown, so only the general rule can see it.
std::shared_ptr<const ClothModel> AnonymousSheet(int n, const Material& material) {
  LatticePanel panel;
  panel.cols = panel.rows = n;
  ClothModelData data = BuildLatticePanel(panel, material, "sheet");
  data.lattice_rows = data.lattice_cols = 0;
  return ClothModel::Create(data);
}

/// An n×n triangulated unit square in the x–z plane, diagonals alternating, inner vertices
/// moved at random by up to 20 % of the spacing.
std::shared_ptr<const ClothModel> IrregularSheet(int n, const Material& material) {
  SurfaceMesh mesh;
  mesh.vertices.resize(n * n, 3);
  std::mt19937 random(7);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  const double h = 1.0 / (n - 1);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const bool inner = i > 0 && j > 0 && i < n - 1 && j < n - 1;
      mesh.vertices.row(i * n + j) << -0.5 + h * (j + (inner ? jitter(random) : 0.0)), 0.0,
          -0.5 + h * (i + (inner ? jitter(random) : 0.0));
    }
  }
  for (int i = 0; i + 1 < n; ++i) {
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
      if ((i + j) % 2 == 0) {
        mesh.faces.push_back({a, c, d});
        mesh.faces.push_back({a, d, b});
      } else {
        mesh.faces.push_back({a, c, b});
        mesh.faces.push_back({b, c, d});
      }
    }
  }
  mesh.source = "irregular test sheet";
  return ClothModel::Create(BuildMeshCloth(mesh, material, "irregular"));
}

TEST(MeshCoarsening, KeepsTheQuincunxSetOfALattice) {
  const int n = 17;
  const auto coarse = CoarsenMesh(*AnonymousSheet(n, Stiff()), 25);
  ASSERT_TRUE(coarse.has_value());
  EXPECT_EQ(static_cast<int>(coarse->fine_index.size()), (n * n + 1) / 2);
  for (int g : coarse->fine_index) EXPECT_EQ((g % n + g / n) % 2, 0) << g;
}

// Interior springs must carry the hand-derived lattice rule K_s = 2k_d, K_d = k_s/2,
// K_b = k_b/2 (docs/pyramid.md), and connect the same pairs as the quincunx pyramid's level 1.
TEST(MeshCoarsening, ReproducesTheLatticeRuleAwayFromTheBorder) {
  const int n = 33;
  Material material = Stiff();
  material.shear_stiffness = 60.0;  // unequal families, so a swapped rule would show
  const auto fine = AnonymousSheet(n, material);
  const auto coarse = CoarsenMesh(*fine, 25);
  ASSERT_TRUE(coarse.has_value());
  std::map<SpringKind, double> fine_k;
  for (const Spring& s : fine->springs()) fine_k[s.kind] = s.stiffness;

  auto interior = [&](int coarse_index) {
    const int g = coarse->fine_index[coarse_index], i = g / n, j = g % n;
    return i >= 4 && j >= 4 && i < n - 4 && j < n - 4;
  };
  int checked[3] = {0, 0, 0};
  double worst = 0.0;
  for (const Spring& s : coarse->coarse.springs) {
    if (!interior(s.a) || !interior(s.b)) continue;
    double expected = 0.0;
    switch (s.kind) {
      case SpringKind::kStructural: expected = 2.0 * fine_k[SpringKind::kShear]; break;
      case SpringKind::kShear: expected = 0.5 * fine_k[SpringKind::kStructural]; break;
      case SpringKind::kBending: expected = 0.5 * fine_k[SpringKind::kBending]; break;
    }
    worst = std::max(worst, std::abs(s.stiffness / expected - 1.0));
    EXPECT_NEAR(s.stiffness, expected, 0.01 * expected) << SpringKindName(s.kind);
    ++checked[static_cast<int>(s.kind)];
  }
  std::printf("worst interior deviation from the lattice rule: %.4f\n", worst);
  for (int kind = 0; kind < 3; ++kind) EXPECT_GT(checked[kind], 100) << kind;

  // Same pairs and kinds as the lattice pyramid's level 1.
  QuincunxPyramid lattice(ClothModel::Create([&] {
                            LatticePanel panel;
                            panel.cols = panel.rows = n;
                            return BuildLatticePanel(panel, material, "sheet");
                          }()),
                          2);
  std::map<std::pair<int, int>, SpringKind> expected_pairs, found_pairs;
  const PyramidLevel& level1 = lattice.level(1);
  for (const Spring& s : level1.model->springs()) {
    const int a = level1.level0_index[s.a], b = level1.level0_index[s.b];
    expected_pairs[{std::min(a, b), std::max(a, b)}] = s.kind;
  }
  for (const Spring& s : coarse->coarse.springs) {
    const int a = coarse->fine_index[s.a], b = coarse->fine_index[s.b];
    found_pairs[{std::min(a, b), std::max(a, b)}] = s.kind;
  }
  EXPECT_EQ(found_pairs, expected_pairs);
}

using test::IterationsOfOneStep;
using test::SmoothState;

Eigen::VectorXd StepChange(std::shared_ptr<const ClothModel> model, double h) {
  StepperSettings settings;
  settings.method = SolverMethod::kDirect;
  settings.external.gravity.setZero();
  settings.external.air_drag = false;
  ImplicitStepper stepper(model, settings);
  const ClothState before = SmoothState(*model);
  ClothState after = before;
  stepper.Step(after, h, {});
  const Points dv = after.velocities - before.velocities;
  return Eigen::Map<const Eigen::VectorXd>(dv.data(), dv.size());
}

double StepMismatch(const MeshCoarsening& coarsening, const Eigen::VectorXd& fine_dv,
                    std::shared_ptr<const ClothModel> coarse, double h) {
  const Eigen::VectorXd coarse_dv = StepChange(coarse, h);
  Eigen::VectorXd restricted(coarse_dv.size());
  for (std::size_t c = 0; c < coarsening.fine_index.size(); ++c) {
    restricted.segment<3>(3 * c) = fine_dv.segment<3>(3 * coarsening.fine_index[c]);
  }
  return (coarse_dv - restricted).norm() / restricted.norm();
}

// The general rule's version of the lattice test: bound 5 % for the fitted model (measured
// figures are printed and quoted in docs/pyramid.md); the naive model — the same coarse
// springs with the fine level's mean constant per kind and the fine particles' own masses —
// must be off by more than 10 %.
TEST(MeshCoarsening, CoarseStepOfAnIrregularMeshMatchesWhereTheNaiveModelFails) {
  const auto fine = IrregularSheet(33, Stiff());
  const auto coarsening = CoarsenMesh(*fine, 25);
  ASSERT_TRUE(coarsening.has_value());
  const double h = 1.0 / 120.0;
  const Eigen::VectorXd fine_dv = StepChange(fine, h);

  const double fitted = StepMismatch(*coarsening, fine_dv, ClothModel::Create(coarsening->coarse), h);
  ClothModelData naive = coarsening->coarse;
  std::map<SpringKind, std::pair<double, int>> mean;
  for (const Spring& s : fine->springs()) {
    mean[s.kind].first += s.stiffness;
    ++mean[s.kind].second;
  }
  for (Spring& s : naive.springs) {
    s.stiffness = mean[s.kind].first / mean[s.kind].second;
    s.damping = 0.0;
  }
  for (std::size_t c = 0; c < coarsening->fine_index.size(); ++c) {
    naive.masses[c] = fine->masses()[coarsening->fine_index[c]];
  }
  const double naive_mismatch = StepMismatch(*coarsening, fine_dv, ClothModel::Create(naive), h);
  std::printf("irregular mesh: %d → %zu particles, step mismatch %.3f (fitted) vs %.3f (naive)\n",
              fine->num_particles(), coarsening->fine_index.size(), fitted, naive_mismatch);
  EXPECT_LT(fitted, 0.05);
  EXPECT_GT(naive_mismatch, 0.10);
}

TEST(MeshCoarsening, KeepsPinsAndMassAndBuildsAPyramidForMeshes) {
  ClothModelData data = IrregularSheet(33, Stiff())->data();
  data.pinned = {1, 32};  // an odd index the checkerboard would drop
  const auto fine = ClothModel::Create(data);
  QuincunxPyramid pyramid(fine, 0);
  ASSERT_GE(pyramid.num_levels(), 3);
  for (int l = 0; l < pyramid.num_levels(); ++l) {
    const PyramidLevel& level = pyramid.level(l);
    EXPECT_NEAR(level.model->total_mass(), fine->total_mass(), 1e-12) << "level " << l;
    std::vector<int> pinned;
    for (int p : level.model->pinned()) pinned.push_back(level.level0_index[p]);
    std::sort(pinned.begin(), pinned.end());
    EXPECT_EQ(pinned, (std::vector<int>{1, 32})) << "level " << l;
  }
}

// The pyramid of a general mesh is a working multigrid preconditioner: on an irregular
// hanging sheet of stiff cloth one step needs ten times fewer iterations than flat PCG, and on
// a lattice whose lattice structure is hidden it works as well as the quincunx pyramid.
TEST(MeshCoarsening, MultigridOnAMeshNeedsFewerIterationsThanFlatPcg) {
  const Material material = StiffCotton();
  auto pinned = [](ClothModelData data) {
    data.pinned = {0, 64};
    return ClothModel::Create(data);
  };
  const auto irregular = pinned(IrregularSheet(65, material)->data());
  const int flat = IterationsOfOneStep(SolverMethod::kPcg, irregular);
  const int multigrid = IterationsOfOneStep(SolverMethod::kMultigrid, irregular);
  LatticePanel panel;
  panel.cols = panel.rows = 65;
  const auto lattice = pinned(BuildLatticePanel(panel, material, "sheet"));
  const auto hidden = pinned(AnonymousSheet(65, material)->data());
  const int quincunx = IterationsOfOneStep(SolverMethod::kMultigrid, lattice);
  const int general = IterationsOfOneStep(SolverMethod::kMultigrid, hidden);
  std::printf("one step to 1e-6: irregular mesh flat PCG %d, multigrid %d; lattice multigrid "
              "%d (quincunx rule) vs %d (general rule)\n", flat, multigrid, quincunx, general);
  EXPECT_LT(10 * multigrid, flat);
  EXPECT_LE(general, quincunx * 6 / 5);
}

/// An n × n grid of unit-square quads in the x–z plane whose vertex of column j, row i is
/// numbered at[i·n + j]: in row-major order, or shuffled as a file's numbering could be; or
/// of triangles, each quad split along a diagonal chosen at random.
struct QuadGrid {
  SurfaceMesh mesh;
  std::vector<int> at;
};
QuadGrid MakeQuadGrid(int n, bool shuffled, bool split_at_random = false) {
  QuadGrid grid;
  grid.at.resize(n * n);
  std::iota(grid.at.begin(), grid.at.end(), 0);
  std::mt19937 random(11);
  if (shuffled) std::shuffle(grid.at.begin(), grid.at.end(), random);
  grid.mesh.vertices.resize(n * n, 3);
  const double h = 1.0 / (n - 1);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      grid.mesh.vertices.row(grid.at[i * n + j]) << h * j - 0.5, 0.0, h * i - 0.5;
    }
  }
  for (int i = 0; i + 1 < n; ++i) {
    for (int j = 0; j + 1 < n; ++j) {
      const int* row = &grid.at[i * n + j];
      if (!split_at_random) {
        grid.mesh.faces.push_back({row[0], row[n], row[n + 1], row[1]});
      } else if (random() % 2 == 0) {
        grid.mesh.faces.push_back({row[0], row[n], row[n + 1]});
        grid.mesh.faces.push_back({row[0], row[n + 1], row[1]});
      } else {
        grid.mesh.faces.push_back({row[0], row[n], row[1]});
        grid.mesh.faces.push_back({row[1], row[n], row[n + 1]});
      }
    }
  }
  return grid;
}

/// A hanging tube of `around` × `rows` quads, 0.15 m in radius, pinned along its top ring. With
/// `around` odd its structural graph has odd cycles, so it cannot be two-coloured.
std::shared_ptr<const ClothModel> Tube(int around, int rows, const Material& material) {
  SurfaceMesh mesh;
  mesh.vertices.resize(rows * around, 3);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < around; ++j) {
      const double angle = 2.0 * std::numbers::pi * j / around;
      mesh.vertices.row(i * around + j) << 0.15 * std::cos(angle), -0.015 * i,
          0.15 * std::sin(angle);
    }
  }
  for (int i = 0; i + 1 < rows; ++i) {
    for (int j = 0; j < around; ++j) {
      const int top = i * around, next = (j + 1) % around;
      mesh.faces.push_back({top + j, top + next, top + around + next, top + around + j});
    }
  }
  ClothModelData data = BuildMeshCloth(mesh, material, "tube");
  for (int j = 0; j < around; ++j) data.pinned.push_back(j);
  return ClothModel::Create(data);
}

// However a quad mesh is numbered, the kept particles are one colour of its checkerboard, as
// quincunx sampling keeps on a lattice. Greedy index order kept a scattered set of a shuffled
// grid, many of whose dropped particles had a single kept neighbour.
TEST(MeshCoarsening, KeepsTheCheckerboardOfAQuadMeshHoweverItIsNumbered) {
  const int n = 33;
  const QuadGrid grid = MakeQuadGrid(n, true);
  const auto model = ClothModel::Create(BuildMeshCloth(grid.mesh, Stiff(), "shuffled grid"));
  const auto coarse = CoarsenMesh(*model, 25);
  ASSERT_TRUE(coarse.has_value());
  int kept_by_colour[2] = {0, 0};
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      kept_by_colour[(i + j) % 2] += coarse->kept[grid.at[i * n + j]] >= 0;
    }
  }
  const int colour = kept_by_colour[0] > 0 ? 0 : 1;
  EXPECT_EQ(kept_by_colour[1 - colour], 0);
  EXPECT_EQ(kept_by_colour[colour], colour == 0 ? (n * n + 1) / 2 : n * n / 2);
}

// Multigrid on a quad mesh converges as fast whatever its numbering, and nearly as fast when
// the mesh cannot be two-coloured. One step to 1e-6: a shuffled 65 × 65 grid took 1,000
// iterations (unconverged) against 33 in row-major order, and a tube of 65 quads around 46
// against 11 for 64 around, before the coarsening took the two-colouring's order and
// interpolated the dropped particles with a single kept neighbour from their second ring too
// (now 33 and 33, 20 and 11).
TEST(MeshCoarsening, MultigridIsBlindToTheNumberingAndToOddCycles) {
  auto grid_model = [](bool shuffled) {
    const QuadGrid grid = MakeQuadGrid(65, shuffled);
    ClothModelData data = BuildMeshCloth(grid.mesh, StiffCotton(), "grid");
    data.pinned = {grid.at[0], grid.at[64]};
    return ClothModel::Create(data);
  };
  const int ordered = IterationsOfOneStep(SolverMethod::kMultigrid, grid_model(false));
  const int shuffled = IterationsOfOneStep(SolverMethod::kMultigrid, grid_model(true));
  const int even = IterationsOfOneStep(SolverMethod::kMultigrid, Tube(64, 33, StiffCotton()));
  const int odd = IterationsOfOneStep(SolverMethod::kMultigrid, Tube(65, 33, StiffCotton()));
  std::printf("one step to 1e-6, multigrid: grid in row-major order %d, shuffled %d; tube of "
              "64 quads around %d, 65 around %d\n", ordered, shuffled, even, odd);
  EXPECT_LE(shuffled, ordered * 6 / 5);
  EXPECT_LE(odd, even * 2);
}

// On a triangle mesh whose diagonals run at random the pyramid is a working preconditioner:
// one step to 1e-6 needs a fifth of flat PCG's iterations (52 against 476). Before, the
// coarse pairs that do not turn at a dropped particle were all called shear, many of the
// second level's particles were left without structural springs, and multigrid needed 382
// (1,000, unconverged, with the coarsening before that).
TEST(MeshCoarsening, MultigridOnATriangleMeshWithRandomDiagonalsBeatsFlatPcg) {
  const QuadGrid grid = MakeQuadGrid(65, false, true);
  ClothModelData data = BuildMeshCloth(grid.mesh, StiffCotton(), "random diagonals");
  data.pinned = {grid.at[0], grid.at[64]};
  const auto model = ClothModel::Create(data);
  const int flat = IterationsOfOneStep(SolverMethod::kPcg, model);
  const int multigrid = IterationsOfOneStep(SolverMethod::kMultigrid, model);
  std::printf("one step to 1e-6 on random diagonals: flat PCG %d, multigrid %d\n", flat, multigrid);
  EXPECT_LT(5 * multigrid, flat);
}


// Whatever the mesh, coarsening builds finite levels that the pyramid's solvers step: 400
// random grids of 2–13 × 2–13 vertices, numbered in order or shuffled, of quads and of
// triangles split either way, with holes (where a vertex is left in no face the mesh is
// refused with its message and skipped) and up to three pins, each built into a pyramid and
// stepped once by multigrid and by the hierarchical step, finite everywhere.
TEST(MeshCoarsening, CoarsensAndStepsRandomMeshesWithHolesAndPins) {
  std::mt19937 random(2026);
  int stepped = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int n = 2 + static_cast<int>(random() % 12);
    QuadGrid grid = MakeQuadGrid(n, random() % 2 == 0, random() % 2 == 0);
    std::erase_if(grid.mesh.faces, [&](const std::vector<int>&) { return random() % 10 == 0; });
    ClothModelData data;
    try {
      data = BuildMeshCloth(grid.mesh, StiffCotton(), "random grid");
    } catch (const InputError&) {
      continue;
    }
    for (int pins = static_cast<int>(random() % 4); pins > 0; --pins) {
      const int p = static_cast<int>(random() % data.rest_positions.rows());
      if (std::find(data.pinned.begin(), data.pinned.end(), p) == data.pinned.end()) {
        data.pinned.push_back(p);
      }
    }
    std::sort(data.pinned.begin(), data.pinned.end());
    const auto model = ClothModel::Create(data);
    for (SolverMethod method : {SolverMethod::kMultigrid, SolverMethod::kHierarchical}) {
      StepperSettings settings;
      settings.method = method;
      const auto pyramid = MakePyramid(model, settings);
      for (int l = 1; l < pyramid->num_levels(); ++l) {
        for (const Spring& s : pyramid->level(l).model->springs()) {
          ASSERT_TRUE(std::isfinite(s.stiffness) && s.stiffness >= 0.0) << trial;
        }
      }
      ImplicitStepper stepper(model, settings, MakeStepSolver(*model, settings, pyramid));
      ClothState state = ClothState::AtRest(*model);
      stepper.Step(state, 1.0 / 60.0, {});
      ASSERT_TRUE(state.positions.allFinite()) << "trial " << trial;
      ++stepped;
    }
  }
  std::printf("random meshes stepped: %d of 800\n", stepped);
  EXPECT_GT(stepped, 400);  // most meshes are not refused
}

}  // namespace
}  // namespace costume::sim
