// Lattice panels: the 12-neighbour springs of the paper's Figure 2a, counted by hand, and
// material parameters independent of the sampling.
#include "sim_core/cloth/lattice_panel.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

LatticePanel Square(int n) {
  LatticePanel panel;
  panel.cols = panel.rows = n;
  return panel;
}

std::map<SpringKind, int> CountKinds(const ClothModelData& data) {
  std::map<SpringKind, int> count;
  for (const Spring& s : data.springs) ++count[s.kind];
  return count;
}

TEST(BuildLatticePanel, HasTheSpringCountsOfTheTwelveNeighbourLattice) {
  for (int n : {3, 5, 33}) {
    const auto data = BuildLatticePanel(Square(n), Material{}, "sheet");
    const auto count = CountKinds(data);
    // n rows of n−1 horizontal links, twice; (n−1)² cells with two diagonals; n rows of n−2
    // skip-one links, twice.
    EXPECT_EQ(count.at(SpringKind::kStructural), 2 * n * (n - 1));
    EXPECT_EQ(count.at(SpringKind::kShear), 2 * (n - 1) * (n - 1));
    EXPECT_EQ(count.at(SpringKind::kBending), 2 * n * (n - 2));
  }
}

TEST(BuildLatticePanel, InteriorParticleHasTwelveNeighbours) {
  const auto data = BuildLatticePanel(Square(7), Material{}, "sheet");
  const int centre = 3 * 7 + 3;
  std::set<int> neighbours;
  for (const Spring& s : data.springs) {
    if (s.a == centre) neighbours.insert(s.b);
    if (s.b == centre) neighbours.insert(s.a);
  }
  EXPECT_EQ(neighbours.size(), 12u);
}

TEST(BuildLatticePanel, RestLengthsAreHDiagonalAndTwoH) {
  const int n = 9;
  const double h = 1.0 / (n - 1);
  const auto data = BuildLatticePanel(Square(n), Material{}, "sheet");
  for (const Spring& s : data.springs) {
    const double expected = s.kind == SpringKind::kStructural ? h
                            : s.kind == SpringKind::kShear    ? h * std::sqrt(2.0)
                                                              : 2 * h;
    EXPECT_NEAR(s.rest_length, expected, 1e-12);
  }
}

TEST(BuildLatticePanel, TotalMassAndStiffnessesAreIndependentOfSampling) {
  Material material;
  material.density = 0.3;
  material.stretch_stiffness = 800;
  material.bending_rigidity = 2e-5;
  material.damping = 2e-3;
  for (int n : {5, 17, 65}) {
    const double h = 1.0 / (n - 1);
    const auto data = BuildLatticePanel(Square(n), material, "sheet");
    EXPECT_NEAR(data.masses.sum(), 0.3, 1e-12);  // 0.3 kg/m² × 1 m²
    for (const Spring& s : data.springs) {
      const double k = s.kind == SpringKind::kBending ? 2e-5 / (h * h) : 800.0;
      if (s.kind != SpringKind::kShear) {
        EXPECT_NEAR(s.stiffness, k, 1e-9 * k);
      }
      EXPECT_NEAR(s.damping, 2e-3 * s.stiffness, 1e-12 * s.stiffness);
    }
  }
}

TEST(BuildLatticePanel, RefusesBadPanelsNamingTheField) {
  LatticePanel panel = Square(1);
  try {
    BuildLatticePanel(panel, Material{}, "skirt");
    FAIL() << "a 1×1 panel was accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("garment 'skirt' panel.cols = 1"), std::string::npos);
  }
  panel = Square(5);
  panel.width = -1;
  EXPECT_THROW(BuildLatticePanel(panel, Material{}, "skirt"), InputError);
  panel = Square(5);
  panel.v_axis = panel.u_axis;
  EXPECT_THROW(BuildLatticePanel(panel, Material{}, "skirt"), InputError);
}

// Each fabric field just beyond its bound is refused, naming the field and the bound; at the
// bound it is accepted. The bounds lie far beyond real fabrics (catalog/fabric_presets.cc).
TEST(BuildLatticePanel, RefusesAFabricBeyondItsBoundsNamingTheField) {
  struct Case {
    double Material::*field;
    const char* name;
    double bound;
    const char* quoted;
  };
  const Case cases[] = {
      {&Material::density, "density", kMaxDensity, "up to 100000 kg/m²"},
      {&Material::stretch_stiffness, "stretch_stiffness", kMaxStiffness, "to 1e+08 N/m"},
      {&Material::shear_stiffness, "shear_stiffness", kMaxStiffness, "to 1e+08 N/m"},
      {&Material::bending_rigidity, "bending_rigidity", kMaxBendingRigidity, "to 100 N·m"},
      {&Material::damping, "damping", kMaxDamping, "to 10 s"},
      {&Material::air_drag, "air_drag", kMaxAirDrag, "to 100 N·s/m per m²"},
      {&Material::friction, "friction", kMaxFriction, "0 to 2"},
      {&Material::structural_spring_k, "structural_spring_k", kMaxStiffness, "to 1e+08 N/m"},
      {&Material::shear_spring_k, "shear_spring_k", kMaxStiffness, "to 1e+08 N/m"},
      {&Material::bending_spring_k, "bending_spring_k", kMaxStiffness, "to 1e+08 N/m"},
  };
  for (const Case& c : cases) {
    Material material;
    material.*c.field = c.bound;
    EXPECT_NO_THROW(BuildLatticePanel(Square(5), material, "skirt")) << c.name;
    material.*c.field = c.bound * 1.001;
    try {
      BuildLatticePanel(Square(5), material, "skirt");
      ADD_FAILURE() << c.name << " beyond its bound was accepted";
    } catch (const InputError& error) {
      const std::string message = error.what();
      EXPECT_NE(message.find(std::string("garment 'skirt' material.") + c.name), std::string::npos)
          << message;
      EXPECT_NE(message.find(c.quoted), std::string::npos) << message;
    }
  }
}

TEST(ClothModelCreate, RefusesEachKindOfBadModel) {
  const auto good = BuildLatticePanel(Square(3), Material{}, "sheet");
  auto expect_refused = [](ClothModelData data, const std::string& words) {
    try {
      ClothModel::Create(std::move(data));
      ADD_FAILURE() << "accepted; expected a refusal mentioning: " << words;
    } catch (const InputError& error) {
      EXPECT_NE(std::string(error.what()).find(words), std::string::npos) << error.what();
    }
  };
  EXPECT_NO_THROW(ClothModel::Create(good));
  auto bad = good;
  bad.masses[4] = 0.0;
  expect_refused(bad, "particle 4 mass = 0 kg");
  bad = good;
  bad.masses[2] = std::nan("");
  expect_refused(bad, "mass = nan");
  bad = good;
  bad.rest_positions(1, 2) = INFINITY;
  expect_refused(bad, "position = inf");
  bad = good;  // a damaged edited-garment file's flipped bit
  bad.rest_positions(1, 0) = -1.4e37;
  expect_refused(bad,
                 "particle 1 position = -1.4e+37 m is out of range: allowed -10000 to 10000 m");
  bad = good;
  bad.springs[3].stiffness = -5;
  expect_refused(bad, "stiffness = -5 N/m");
  bad = good;
  bad.springs[0].rest_length = 0;
  expect_refused(bad, "rest_length = 0 m");
  bad = good;
  bad.springs.push_back(bad.springs[0]);
  expect_refused(bad, "duplicates another spring");
  bad = good;
  bad.springs[0].b = bad.springs[0].a;
  expect_refused(bad, "to itself");
  bad = good;
  bad.springs[0].b = 99;
  expect_refused(bad, "particle index = 99 is out of range: allowed 0 to 8");
  bad = good;
  bad.pinned = {0, 0};
  expect_refused(bad, "pinned twice");
  bad = good;
  bad.masses.resize(0);
  bad.areas.resize(0);
  bad.rest_positions.resize(0, 3);
  expect_refused(bad, "has no particles");
}

TEST(FindNearestParticles, RefusesAPinPointFarFromTheCloth) {
  const auto data = BuildLatticePanel(Square(3), Material{}, "sheet");
  EXPECT_EQ(FindNearestParticles(data.rest_positions, {Eigen::Vector3d(0.5, 0, 0.5)}, 1e-3, "x"),
            std::vector<int>{8});
  EXPECT_THROW(FindNearestParticles(data.rest_positions, {Eigen::Vector3d(0, 1, 0)}, 1e-3, "x"),
               InputError);
}

}  // namespace
}  // namespace costume::sim
