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
  return FindFabricPreset("cotton").fabric;  // scenes/garment.toml's
}

}  // namespace costume::catalog
