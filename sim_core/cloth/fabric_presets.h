#pragma once
/// @file
/// The named fabrics at their measured stiffness (cotton, silk, wool, denim, leather): one
/// table that scene files (`base = "cotton"`, `material = "silk"`), the catalogue and the
/// GUI all read, so a preset means the same figures everywhere. Sources and conversions
/// (Kawabata's KES-F measurements): docs/catalog.md, "Fabric presets".

#include <string>
#include <vector>

#include "sim_core/cloth/material.h"

namespace costume::sim {

/// A named fabric and where its figures come from.
struct FabricPreset {
  std::string name;
  /// The fabric, named `name`; air drag the engine's default (no measurement).
  Material material;
  /// One line on the figures' source.
  std::string source;
};

/// Every preset: cotton, silk, wool, denim, leather (in that order).
const std::vector<FabricPreset>& FabricPresets();

/// The preset called `name`, or null.
const FabricPreset* FindFabricPreset(const std::string& name);

}  // namespace costume::sim
