#include "catalog/fabric_presets.h"

#include "sim_core/cloth/fabric_presets.h"
#include "sim_core/common/input_error.h"

namespace costume::catalog {

const std::vector<FabricPreset>& FabricPresets() {
  // The engine's presets (sim_core/cloth/fabric_presets.h): one table for scene files, the
  // catalogue and the GUI.
  static const std::vector<FabricPreset> presets = [] {
    std::vector<FabricPreset> list;
    for (const sim::FabricPreset& preset : sim::FabricPresets()) {
      list.push_back({preset.name, FabricFromMaterial(preset.material), preset.source});
    }
    return list;
  }();
  return presets;
}

const FabricPreset& FindFabricPreset(const std::string& name) {
  std::string known;
  for (const FabricPreset& preset : FabricPresets()) {
    if (preset.name == name) return preset;
    known += (known.empty() ? "" : ", ") + preset.name;
  }
  throw sim::InputError("fabric preset '" + name + "' is unknown: the presets are " + known);
}

FabricParameters BuiltInGarmentFabric() {
  // scenes/garment.toml's [[material]] "skirt_cotton".
  FabricParameters f;
  f.mass_per_area = 0.15;
  f.stretch_stiffness = 300.0;
  f.shear_stiffness = 300.0;
  f.bend_stiffness = 5e-6;
  f.damping = 1e-3;
  f.friction = 0.5;
  return f;
}

}  // namespace costume::catalog
