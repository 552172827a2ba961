#pragma once
/// @file
/// What the cloth-side adaptive regions of the mesh collider (sim_core/collision/
/// cloth_regions.h) save, on (a) a flat sheet lying 2 mm above the flat top of a box-shaped
/// skinned avatar and (b) the same sheet folded into tight zig-zag folds over it.
/// FindContacts runs in blocks of calls per mode (regions off, fixed base regions, adaptive
/// regions), the modes taking turns, so machine noise hits every mode alike while each keeps
/// its data in cache within its block (the first call of a block is not timed). Used by
/// collision_regions_bench and collision_bench. Single-threaded.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

namespace costume::tools {

/// The modes, in the order of RegionsComparisonSettings::only.
inline constexpr const char* kRegionModes[] = {"off", "fixed", "adaptive"};

struct RegionsComparisonSettings {
  int n = 65;                     // sheet lattice size
  double sheet_size = 1.0;        // [m]
  double box_size = 1.2;          // top face edge [m]
  double cell = 0.02;             // body triangle grid spacing [m]
  int reps = 200;
  int block = 10;
  double fold_height = 0.012;     // zig-zag amplitude [m]
  double max_penetration = 0.05;  // MeshCollisionOptions::max_penetration [m]
  std::uint32_t seed = 1;
  /// Run only this mode (−1: all three, side by side), for profiling one of them.
  int only = -1;
  /// MeshCollisionOptions::reuse_bounds: false makes every call search as the first does.
  bool reuse_bounds = true;
};

/// Per sheet ("flat", "folded" or "both"): each mode's median ms per call, tests, broad-phase
/// queries and contacts, and the savings in percent (adaptive vs off, fixed vs off, adaptive
/// vs fixed; positive = less work), with the settings, as JSON.
nlohmann::json CompareClothRegions(const RegionsComparisonSettings& settings,
                                   const std::string& sheet_case = "both");

}  // namespace costume::tools
