#include "sim_core/cloth/fabric_presets.h"

namespace costume::sim {

namespace {

// Unit conversions from Kawabata's KES-F units (docs/catalog.md):
/// Bending rigidity B: 1 gf·cm²/cm = 1 gf·cm = 9.80665e-3 N · 1e-2 m [N·m].
constexpr double kGfCm2PerCm = 9.80665e-5;
/// Shear rigidity G: 1 gf/(cm·degree) = 9.80665e-3 N / 1e-2 m per π/180 rad [N/m].
constexpr double kGfPerCmDegree = 0.980665 * 180.0 / 3.141592653589793;
/// KES-F's tensile test stops at 500 gf/cm = 490.3 N/m; EMT is the strain reached there.
constexpr double kEmtLoad = 490.3325;

/// A fabric from mass per area [kg/m²], EMT [-], G [gf/(cm·deg)], B [gf·cm²/cm] and its
/// friction against skin [-].
FabricPreset Make(const char* name, double mass_per_area, double emt, double shear_g,
                  double bending_b, double friction, const char* source) {
  Material m;
  m.name = name;
  m.density = mass_per_area;
  m.stretch_stiffness = kEmtLoad / emt;  // secant stiffness up to the KES-F load
  m.shear_stiffness = shear_g * kGfPerCmDegree;
  m.bending_rigidity = bending_b * kGfCm2PerCm;
  m.damping = 1e-3;  // the engine's default damping time (an estimate, as for every preset)
  m.friction = friction;
  return {name, m, source};
}

}  // namespace

const std::vector<FabricPreset>& FabricPresets() {
  static const std::vector<FabricPreset> presets = {
      Make("cotton", 0.12, 0.05, 1.0, 0.08, 0.4,
           "poplin 120 g/m²; KES-F shirting EMT 5%, G 1.0, B 0.08; skin friction 0.4"),
      Make("silk", 0.06, 0.08, 0.4, 0.03, 0.25,
           "crepe de chine 14 momme (61 g/m²); KES-F EMT 8%, G 0.4, B 0.03; skin friction 0.25"),
      Make("wool", 0.25, 0.06, 0.6, 0.12, 0.45,
           "worsted suiting 250 g/m²; KES-F EMT 6%, G 0.6, B 0.12; skin friction 0.45"),
      Make("denim", 0.40, 0.03, 3.0, 1.0, 0.45,
           "12 oz/yd² (407 g/m²); KES-F EMT 3%, G 3, B 1.0 (estimate); skin friction 0.45"),
      Make("leather", 0.55, 0.02, 10.0, 3.0, 0.55,
           "lamb nappa 0.7 mm; estimates: E·t ≈ 25 kN/m, G 10, B 3 (E·t³/12); skin friction "
           "0.55"),
  };
  return presets;
}

const FabricPreset* FindFabricPreset(const std::string& name) {
  for (const FabricPreset& preset : FabricPresets()) {
    if (preset.name == name) return &preset;
  }
  return nullptr;
}

}  // namespace costume::sim
