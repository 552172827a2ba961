#pragma once
/// @file
/// Named fabric presets (cotton, silk, wool, denim, leather) in physical units. Each value's
/// source (Kawabata KES-F measurements, textile weights, skin-friction studies, Blender's
/// presets as a cross-check) and which values are estimates: docs/catalog.md.

#include <string>
#include <vector>

#include "catalog/catalog.h"

namespace costume::catalog {

/// A named preset.
struct FabricPreset {
  std::string name;
  FabricParameters fabric;
  /// One line on where the numbers come from (docs/catalog.md has the full table).
  std::string source;
};

/// Every preset: cotton, silk, wool, denim, leather (in that order).
const std::vector<FabricPreset>& FabricPresets();

/// The preset `name`; throws sim::InputError listing the known names for an unknown one.
const FabricPreset& FindFabricPreset(const std::string& name);

/// The fabric of the built-in garments (skirt, cape, dress) and of imported MakeHuman
/// garments: the cotton preset, as scenes/garment.toml wears it.
FabricParameters BuiltInGarmentFabric();

}  // namespace costume::catalog
