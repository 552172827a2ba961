// A strip hung from its top edge stretches under its own weight by what the springs' law
// gives, with the strain limit on: the limit takes back only what a linearised step adds by
// turning springs, never the fabric's elastic stretch (strain_limit.h). The oracle is the
// chain's statics written here: in each column the spring j links from the bottom carries
// the weight of the j particles below it, and stretches by j·m·g / k.
#include <gtest/gtest.h>

#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"
#include "sim_core/solver/strain_limit.h"

namespace costume::sim {
namespace {

constexpr int kCols = 3, kRows = 26;
constexpr double kWidth = 0.04, kLength = 0.5;  // m: 2 cm spacing
constexpr double kStretch = 500.0;              // N/m

/// The strip with the top spring at `top_strain` under the strip's own weight.
SceneDescription Strip(double top_strain, double strain_limit) {
  const double spacing = kLength / (kRows - 1);
  // A spring of a lattice of spacing h pulls k·h per unit strain (lattice_panel.h): the top
  // one carries the (rows − 1) particles below it.
  const double particle_mass = top_strain * kStretch * spacing / ((kRows - 1) * 9.81);
  Material fabric;
  fabric.name = "strip";
  fabric.density = particle_mass * kCols * kRows / (kWidth * kLength);
  fabric.stretch_stiffness = kStretch;
  fabric.shear_stiffness = 0.0;  // no diagonal or bending spring takes any of the load
  fabric.bending_rigidity = 0.0;
  fabric.damping = 0.05;  // s: overdamped, so that 3 s settle it
  SceneDescription scene;
  scene.name = "strip";
  scene.duration = 3.0;
  scene.solver.tolerance = 1e-6;
  scene.solver.strain_limit = strain_limit;
  scene.materials.push_back(fabric);
  GarmentSpec strip;
  strip.name = "strip";
  strip.material = fabric.name;
  strip.panel = LatticePanel{};
  strip.panel->origin = Eigen::Vector3d::Zero();
  strip.panel->u_axis = Eigen::Vector3d::UnitX();
  strip.panel->v_axis = -Eigen::Vector3d::UnitY();  // rows run down
  strip.panel->width = kWidth;
  strip.panel->height = kLength;
  strip.panel->cols = kCols;
  strip.panel->rows = kRows;
  for (int j = 0; j < kCols; ++j) {
    strip.pin_points.emplace_back(j * kWidth / (kCols - 1), 0.0, 0.0);
  }
  scene.garments.push_back(strip);
  return scene;
}

/// How far the bottom row has dropped below its rest height after the run [m].
double SettledDrop(const SceneDescription& scene) {
  auto simulation = Simulation::Build(scene);
  for (int f = 0; f < simulation->num_frames(); ++f) simulation->AdvanceFrame();
  double drop = 0.0;
  for (int j = 0; j < kCols; ++j) {
    const int bottom = (kRows - 1) * kCols + j;
    drop += -kLength - simulation->state().positions(bottom, 1);
  }
  return drop / kCols;
}

/// The chain's statics: Σ_{j=1}^{rows−1} j·m·g / k, with k = kStretch per spring.
double ExpectedDrop(double top_strain) {
  const double spacing = kLength / (kRows - 1);
  const double per_particle = top_strain * spacing / (kRows - 1);  // m·g / k [m]
  return per_particle * (kRows - 1) * kRows / 2.0;
}

TEST(StripUnderLoad, StretchesByTheSpringsLawWithTheStrainLimitOn) {
  for (double top_strain : {0.004, 0.04}) {  // below and well above kFreeStretch
    const double expected = ExpectedDrop(top_strain);
    EXPECT_NEAR(SettledDrop(Strip(top_strain, 0.1)), expected, 0.02 * expected)
        << "top strain " << top_strain;
  }
}

TEST(StripUnderLoad, StretchesTheSameWithTheLimitOff) {
  const double top_strain = 0.04;
  const double with = SettledDrop(Strip(top_strain, 0.1));
  const double without = SettledDrop(Strip(top_strain, 0.0));
  EXPECT_NEAR(with, without, 0.005 * without);
}

TEST(StripUnderLoad, TheCapHoldsALoadBeyondIt) {
  // A load that would stretch the top spring 30 % is held at the 10 % cap there.
  auto simulation = Simulation::Build(Strip(0.3, 0.1));
  for (int f = 0; f < simulation->num_frames(); ++f) simulation->AdvanceFrame();
  const StrainStats strain = StructuralStrain(simulation->model(), simulation->state().positions);
  EXPECT_LE(strain.max, 0.1 + StrainLimitSettings{}.tolerance);
  EXPECT_GT(strain.max, 0.09);
}

}  // namespace
}  // namespace costume::sim
