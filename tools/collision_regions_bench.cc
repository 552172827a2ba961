/// @file
/// collision_regions_bench: what the cloth-side adaptive regions of the mesh collider
/// (sim_core/collision/cloth_regions.h) save, on (a) a flat 65×65 sheet lying 2 mm above
/// the flat top of a box-shaped skinned avatar and (b) the same sheet folded into tight
/// zig-zag folds over it (tools/regions_comparison.h; collision_bench prints the same
/// comparison with its garment figures). Prints one JSON object on stdout. Single-threaded.

#include <CLI/CLI.hpp>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "tools/regions_comparison.h"

int main(int argc, char** argv) {
  costume::tools::RegionsComparisonSettings s;
  CLI::App app{"Cloth-side adaptive collision regions: flat and folded sheet on a box avatar"};
  app.add_option("--n", s.n, "sheet lattice size (n × n)")->check(CLI::Range(3, 1025));
  app.add_option("--sheet-size", s.sheet_size, "sheet edge [m]")->check(CLI::PositiveNumber);
  app.add_option("--box-size", s.box_size, "avatar box top face edge [m]")
      ->check(CLI::PositiveNumber);
  app.add_option("--cell", s.cell, "avatar triangle grid spacing [m]")
      ->check(CLI::PositiveNumber);
  app.add_option("--reps", s.reps, "repetitions per mode")->check(CLI::Range(1, 100000));
  app.add_option("--block", s.block, "consecutive calls per mode before the next takes its turn")
      ->check(CLI::Range(2, 1000));
  app.add_option("--fold-height", s.fold_height, "zig-zag fold height [m]")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-penetration", s.max_penetration,
                 "collider's max_penetration [m]: sets how far each particle searches")
      ->check(CLI::PositiveNumber);
  app.add_flag("!--no-memory", s.reuse_bounds,
               "collider forgets between calls (reuse_bounds = false): each call a first one");
  std::string sheet_case = "both";
  app.add_option("--case", sheet_case, "sheet to run: flat, folded or both")
      ->check(CLI::IsMember({"both", "flat", "folded"}));
  std::string only = "all";
  app.add_option("--only", only, "run one mode only (for profiling): off, fixed or adaptive")
      ->check(CLI::IsMember({"all", "off", "fixed", "adaptive"}));
  CLI11_PARSE(app, argc, argv);
  for (int mode = 0; mode < 3; ++mode) {
    if (only == costume::tools::kRegionModes[mode]) s.only = mode;
  }
  try {
    const nlohmann::json out = costume::tools::CompareClothRegions(s, sheet_case);
    std::cout << out.dump(2) << "\n";
  } catch (const std::exception& e) {
    std::cerr << "collision_regions_bench: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
