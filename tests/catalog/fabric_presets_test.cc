// The fabric presets: physical ranges, the KES-F unit conversions, and that each one makes a
// material the engine accepts and simulates stably.

#include "catalog/fabric_presets.h"

#include <gtest/gtest.h>

#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"
#include "tests/support/test_scenes.h"

namespace costume::catalog {
namespace {

TEST(FabricPresets, AreTheFiveFabricsInPhysicalRanges) {
  std::vector<std::string> names;
  for (const FabricPreset& preset : FabricPresets()) {
    names.push_back(preset.name);
    const FabricParameters& f = preset.fabric;
    SCOPED_TRACE(preset.name);
    // Woven and leather garment fabrics: 30 g/m² (chiffon) to 1 kg/m² (heavy leather);
    // KES-F tensile secant stiffness 1 to 100 kN/m; shear rigidity 0.1 to 20 gf/(cm·°),
    // i.e. 5 to 1200 N/m; bending rigidity 0.005 to 20 gf·cm²/cm, i.e. 5e-7 to 2e-3 N·m;
    // skin friction 0.1 to 1.
    EXPECT_GE(f.mass_per_area, 0.03);
    EXPECT_LE(f.mass_per_area, 1.0);
    EXPECT_GE(f.stretch_stiffness, 1e3);
    EXPECT_LE(f.stretch_stiffness, 1e5);
    EXPECT_GE(f.shear_stiffness, 5.0);
    EXPECT_LE(f.shear_stiffness, 1200.0);
    EXPECT_GE(f.bend_stiffness, 5e-7);
    EXPECT_LE(f.bend_stiffness, 2e-3);
    EXPECT_GE(f.friction, 0.1);
    EXPECT_LE(f.friction, 1.0);
    EXPECT_GE(f.damping, 0.0);
    EXPECT_FALSE(preset.source.empty());
    // Woven fabrics resist stretch far more than shear, and shear far more than bending.
    EXPECT_GT(f.stretch_stiffness, 10 * f.shear_stiffness);
    EXPECT_NO_THROW(sim::ValidateMaterial(MaterialFromFabric(f, preset.name), preset.name));
  }
  EXPECT_EQ(names, (std::vector<std::string>{"cotton", "silk", "wool", "denim", "leather"}));
}

TEST(FabricPresets, OrderAsTheFabricsDo) {
  auto get = [](const std::string& name) { return FindFabricPreset(name).fabric; };
  EXPECT_LT(get("silk").mass_per_area, get("cotton").mass_per_area);
  EXPECT_LT(get("cotton").mass_per_area, get("wool").mass_per_area);
  EXPECT_LT(get("wool").mass_per_area, get("denim").mass_per_area);
  EXPECT_LT(get("silk").bend_stiffness, get("cotton").bend_stiffness);
  EXPECT_LT(get("denim").bend_stiffness, get("leather").bend_stiffness);
  // Blender's presets agree on the order: leather bends stiffest (150 vs denim's 10, cotton's
  // 0.5, silk's 0.05 in Blender's units), and stretches stiffest.
  EXPECT_GT(get("leather").stretch_stiffness, get("denim").stretch_stiffness);
  EXPECT_GT(get("denim").stretch_stiffness, get("cotton").stretch_stiffness);
  EXPECT_GT(get("cotton").stretch_stiffness, get("silk").stretch_stiffness);
}

TEST(FabricPresets, ConvertKawabataUnits) {
  // Cotton: B = 0.08 gf·cm²/cm; 1 gf = 9.80665e-3 N, 1 cm²/cm = 1e-2 m: 7.85 µN·m.
  EXPECT_NEAR(FindFabricPreset("cotton").fabric.bend_stiffness, 0.08 * 9.80665e-3 * 1e-2, 1e-15);
  EXPECT_NEAR(FindFabricPreset("cotton").fabric.bend_stiffness, 7.845e-6, 1e-9);
  // G = 1 gf/(cm·°) = 9.80665e-3 N / 1e-2 m / (π/180) = 56.19 N/m.
  EXPECT_NEAR(FindFabricPreset("cotton").fabric.shear_stiffness, 56.19, 0.01);
  // EMT = 5 % at 500 gf/cm = 490.33 N/m: secant stiffness 9806.65 N/m.
  EXPECT_NEAR(FindFabricPreset("cotton").fabric.stretch_stiffness, 9806.65, 0.01);
}

TEST(FabricPresets, ConvertToAndFromMaterials) {
  const FabricParameters denim = FindFabricPreset("denim").fabric;
  const sim::Material material = MaterialFromFabric(denim, "denim");
  EXPECT_EQ(material.density, denim.mass_per_area);
  EXPECT_EQ(material.bending_rigidity, denim.bend_stiffness);
  const FabricParameters back = FabricFromMaterial(material);
  EXPECT_EQ(back.stretch_stiffness, denim.stretch_stiffness);
  EXPECT_EQ(back.shear_stiffness, denim.shear_stiffness);
  EXPECT_EQ(back.damping, denim.damping);
  EXPECT_EQ(back.friction, denim.friction);
  try {
    FindFabricPreset("chiffon");
    FAIL() << "no throw";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("leather"), std::string::npos) << error.what();
  }
}

// Each preset hangs stably at 60 Hz with one step per frame (the engine refuses steps it
// cannot trust, and rolls back non-finite ones).
TEST(FabricPresets, HangStablyAtSixtyHertz) {
  for (const FabricPreset& preset : FabricPresets()) {
    auto simulation =
        sim::Simulation::Build(test::HangScene(17, MaterialFromFabric(preset.fabric, preset.name)));
    int rolled_back = 0;
    for (int frame = 0; frame < 60; ++frame) {
      rolled_back += simulation->AdvanceFrame().rolled_back_steps;
    }
    EXPECT_EQ(rolled_back, 0) << preset.name;
    EXPECT_TRUE(simulation->state().positions.allFinite()) << preset.name;
    // Hanging from its two top corners the sheet has fallen, not flown away.
    const double lowest = simulation->state().positions.col(1).minCoeff();
    EXPECT_LT(lowest, -0.3) << preset.name;
    EXPECT_GT(lowest, -1.6) << preset.name;
  }
}

}  // namespace
}  // namespace costume::catalog
