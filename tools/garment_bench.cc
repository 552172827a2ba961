/// @file
/// garment_bench: garments × avatars × clips × fabric presets, each run with no solver
/// settings (what the engine chooses itself), measured every frame by sim::GarmentMetrics
/// against independent yardsticks: the structural springs' strain, the depth of cloth inside
/// the true skinned mesh, the cloth edges through the cloth. Prints one JSON line per case,
/// then a summary table (Markdown) against the targets, and writes a contact sheet PNG per
/// case (frames at fixed times, drawn offscreen) so a person can look. docs/benchmarks.md
/// gives the command and the current table.
///
/// Cases: the built-in skirt, dress and cape on the built-in humanoid, the MakeHuman body and
/// CesiumMan; every MakeHuman garment of ../shared/data on the MakeHuman body; clips built in
/// (walk, run, kick, jump, dance) and from files (CMU walk and kick, DeepMimic walk, run,
/// jump, kick, dance), and any avatar or clip file given with --avatar-file / --clip-file.
/// By default each case takes one fabric, the presets in turn; --all-fabrics runs each case
/// in every preset. Single-threaded.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "assets/avatar_import.h"
#include "assets/clip_import.h"
#include "assets/makehuman_import.h"
#include "assets/run_summary_json.h"
#include "render/contact_sheet.h"
#include "render/image.h"
#include "sim_core/avatar/garment_patterns.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/cloth/fabric_presets.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/garment_metrics.h"
#include "sim_core/scene/simulation.h"

namespace {

using namespace costume;
namespace fs = std::filesystem;
using nlohmann::json;

/// The targets of the garment issue (docs/benchmarks.md, "Garments").
constexpr double kTargetMeanStrain = 0.01;
constexpr double kTargetMaxStrain = 0.10;
constexpr double kTargetMaxStrainP99 = 0.05;
constexpr double kTargetPenetrationMm = 1.0;
constexpr double kTargetMsSmall = 1000.0 / 60.0;  // up to 3,000 particles
constexpr double kTargetMsLarge = 1000.0 / 30.0;  // up to 10,000

struct Options {
  std::string data_dir = "../shared/data";
  std::vector<std::string> garments{"skirt", "dress", "cape", "makehuman"};
  std::vector<std::string> avatars{"builtin", "makehuman", "cesiumman"};
  std::vector<std::string> clips{"walk",     "run",     "kick",    "jump",    "dance",
                                 "cmu_walk", "cmu_kick", "dm_walk", "dm_run", "dm_jump",
                                 "dm_kick",  "dm_dance"};
  std::vector<std::string> fabrics{"cotton", "silk", "wool", "denim", "leather"};
  std::vector<std::string> avatar_files, clip_files;
  bool all_fabrics = false;
  double seconds = 4.0;
  bool self_collision = false;
  std::string sheets = "out/garment_bench";
  int sheet_tile = 192;
  std::vector<double> sheet_times{0.5, 1.0, 1.5, 2.0, 3.0, 4.0};
  int resolution = 64;
  /// "" = the engine's choice; else pcg, multigrid or multigrid_galerkin (measurement only).
  std::string solver;
  /// The solver's threads (1: the figures of one core, as the targets are set).
  int threads = 1;
};

/// An avatar the bench dresses, loaded once.
struct AvatarCase {
  std::string name;
  std::shared_ptr<const sim::Avatar> avatar;
  /// MakeHuman's body, which its garments are made for (null otherwise).
  bool makehuman = false;
};

/// A garment: a built-in pattern, or a MakeHuman garment (only for its own body).
struct GarmentCase {
  std::string name;
  std::optional<std::string> pattern;
  fs::path mhclo;
};

struct ClipCase {
  std::string name;
  /// Built-in clip name, or empty for a file.
  std::string builtin;
  fs::path file;
};

/// "NAME=PATH" → (NAME, PATH); a bare PATH is named after its file.
std::pair<std::string, std::string> NamedPath(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos) return {fs::path(text).stem().string(), text};
  return {text.substr(0, eq), text.substr(eq + 1)};
}

std::vector<AvatarCase> LoadAvatars(const Options& options) {
  std::vector<AvatarCase> avatars;
  const fs::path data(options.data_dir);
  for (const std::string& name : options.avatars) {
    if (name == "builtin") {
      avatars.push_back({name, sim::MakeHumanoid(), false});
    } else if (name == "makehuman") {
      const fs::path body = data / "makehuman" / "body";
      if (!fs::exists(body / "base.obj")) {
        std::cerr << "garment_bench: no " << (body / "base.obj") << "; MakeHuman skipped\n";
        continue;
      }
      avatars.push_back({name,
                         assets::LoadMakeHumanAvatar((body / "base.obj").string(),
                                                     (body / "default.mhskel").string(),
                                                     (body / "default_weights.mhw").string()),
                         true});
    } else if (name == "cesiumman") {
      const fs::path file = data / "khronos-cesiumman" / "CesiumMan.glb";
      if (!fs::exists(file)) {
        std::cerr << "garment_bench: no " << file << "; CesiumMan skipped\n";
        continue;
      }
      avatars.push_back({name, assets::LoadAvatar(file.string()), false});
    } else {
      throw sim::InputError("--avatars: '" + name +
                            "' is none of builtin, makehuman, cesiumman (files: --avatar-file)");
    }
  }
  for (const std::string& entry : options.avatar_files) {
    const auto [name, path] = NamedPath(entry);
    avatars.push_back({name, assets::LoadAvatar(path), false});
  }
  return avatars;
}

std::vector<GarmentCase> ListGarments(const Options& options) {
  std::vector<GarmentCase> garments;
  for (const std::string& name : options.garments) {
    const auto& patterns = sim::BuiltInGarmentNames();
    if (std::find(patterns.begin(), patterns.end(), name) != patterns.end()) {
      garments.push_back({name, name, {}});
      continue;
    }
    if (name != "makehuman") {
      throw sim::InputError("--garments: '" + name +
                            "' is none of skirt, dress, cape, makehuman (every MakeHuman "
                            "garment of the data folder)");
    }
    const fs::path clothes = fs::path(options.data_dir) / "makehuman" / "clothes";
    if (!fs::is_directory(clothes)) continue;
    std::vector<fs::path> folders;
    for (const auto& entry : fs::directory_iterator(clothes)) {
      if (entry.is_directory()) folders.push_back(entry.path());
    }
    std::sort(folders.begin(), folders.end());
    for (const fs::path& folder : folders) {
      const fs::path mhclo = folder / (folder.filename().string() + ".mhclo");
      if (fs::exists(mhclo)) garments.push_back({folder.filename().string(), std::nullopt, mhclo});
    }
  }
  return garments;
}

std::vector<ClipCase> ListClips(const Options& options) {
  const fs::path data(options.data_dir);
  const std::map<std::string, fs::path> files = {
      {"cmu_walk", data / "cmu-mocap-bvh" / "02_02.bvh"},
      {"cmu_kick", data / "cmu-mocap-bvh" / "10_01.bvh"},
      {"dm_walk", data / "deepmimic-motions" / "motions" / "humanoid3d_walk.txt"},
      {"dm_run", data / "deepmimic-motions" / "motions" / "humanoid3d_run.txt"},
      {"dm_jump", data / "deepmimic-motions" / "motions" / "humanoid3d_jump.txt"},
      {"dm_kick", data / "deepmimic-motions" / "motions" / "humanoid3d_kick.txt"},
      {"dm_dance", data / "deepmimic-motions" / "motions" / "humanoid3d_dance_a.txt"},
      {"mh_walk", data / "makehuman" / "bvh" / "walk1_mhskel.bvh"},
  };
  std::vector<ClipCase> clips;
  const auto& builtins = sim::BuiltInClipNames();
  for (const std::string& name : options.clips) {
    if (std::find(builtins.begin(), builtins.end(), name) != builtins.end()) {
      clips.push_back({name, name, {}});
      continue;
    }
    const auto file = files.find(name);
    if (file == files.end()) {
      std::string known;
      for (const std::string& b : builtins) known += b + ", ";
      for (const auto& [n, p] : files) known += n + ", ";
      throw sim::InputError("--clips: '" + name + "' is unknown; known: " + known +
                            "or a file with --clip-file");
    }
    if (!fs::exists(file->second)) {
      std::cerr << "garment_bench: no " << file->second << "; clip " << name << " skipped\n";
      continue;
    }
    clips.push_back({name, "", file->second});
  }
  for (const std::string& entry : options.clip_files) {
    const auto [name, path] = NamedPath(entry);
    clips.push_back({name, "", path});
  }
  return clips;
}

std::shared_ptr<const sim::Clip> LoadClipCase(const ClipCase& clip) {
  if (!clip.builtin.empty()) {
    return std::make_shared<const sim::Clip>(
        sim::MakeBuiltInClip(clip.builtin, sim::MakeHumanoidSkeleton()));
  }
  return std::make_shared<const sim::Clip>(assets::LoadClip(clip.file.string()));
}

/// The case's scene: no solver settings, the preset's fabric, the avatar's defaults.
sim::SceneDescription CaseScene(const AvatarCase& avatar, const GarmentCase& garment,
                                std::shared_ptr<const sim::Clip> clip,
                                const sim::FabricPreset& fabric, const Options& options) {
  sim::SceneDescription scene;
  scene.name = garment.name + "_" + avatar.name;
  scene.source = "garment_bench";
  sim::AvatarSpec spec;
  spec.avatar = avatar.avatar;
  spec.clip = std::move(clip);
  scene.avatar = spec;
  scene.duration = spec.motion.fit_time + options.seconds;
  scene.effects.self_collision = options.self_collision;
  sim::GarmentSpec g;
  if (garment.pattern) {
    g.pattern = *garment.pattern;
    g.pattern_resolution = options.resolution;
  } else {
    const fs::path body = fs::path(options.data_dir) / "makehuman" / "body" / "base.obj";
    g = assets::MakeHumanGarmentSpec(garment.mhclo.string(), assets::ReadObj(body.string()),
                                     avatar.avatar->skeleton());
  }
  g.name = garment.name;
  g.material = fabric.name;
  scene.garments.push_back(g);
  scene.solver.threads = options.threads;
  if (options.solver == "pcg") scene.solver.method = sim::SolverMethod::kPcg;
  if (options.solver.starts_with("multigrid")) scene.solver.method = sim::SolverMethod::kMultigrid;
  if (options.solver == "multigrid_galerkin") {
    scene.solver.coarse_operator = sim::CoarseOperator::kGalerkin;
  }
  return scene;
}

struct CaseResult {
  json row;
  sim::RunSummary summary;
};

std::string SheetPath(const Options& options, const std::string& id) {
  std::string file = id;
  for (char& c : file) {
    if (c == '/' || c == ' ') c = '_';
  }
  return (fs::path(options.sheets) / (file + ".png")).string();
}

CaseResult RunCase(const sim::SceneDescription& scene, const std::string& id,
                   const Options& options) {
  const auto build_start = std::chrono::steady_clock::now();
  auto simulation = sim::Simulation::Build(scene);
  const double build_ms = std::chrono::duration<double, std::milli>(
                              std::chrono::steady_clock::now() - build_start)
                              .count();
  sim::GarmentMetrics metrics(*simulation);
  std::vector<render::SheetFrame> sheet;
  std::vector<int> sheet_frames;
  const double fit = scene.avatar->motion.fit_time;
  for (double t : options.sheet_times) {
    sheet_frames.push_back(static_cast<int>(std::lround((fit + t) * scene.frame_rate)));
  }
  for (int f = 1; f <= simulation->num_frames(); ++f) {
    const sim::FrameReport report = simulation->AdvanceFrame();
    metrics.AddFrame(*simulation, report);
    if (std::find(sheet_frames.begin(), sheet_frames.end(), f) != sheet_frames.end()) {
      sheet.push_back({simulation->avatar()->vertices(),
                       simulation->avatar()->avatar().triangles(),
                       simulation->state().positions, simulation->model().triangles()});
    }
  }
  CaseResult result;
  result.summary = metrics.Summary();
  result.row = json::parse(assets::RunSummaryJson(result.summary));
  result.row["build_ms"] = build_ms;
  if (!sheet.empty() && !options.sheets.empty()) {
    const std::string path = SheetPath(options, id);
    render::WritePng(path, render::RenderContactSheet(sheet, options.sheet_tile,
                                                      static_cast<int>(sheet.size())));
    result.row["contact_sheet"] = path;
  }
  return result;
}

/// Whether a run meets every target; edges through the cloth count only with self-collision
/// on (without it, cloth passing through itself is what the scene asked for).
bool MeetsTargets(const sim::RunSummary& s, bool self_collision) {
  const double budget = s.particles <= 3000 ? kTargetMsSmall : kTargetMsLarge;
  return s.mean_strain <= kTargetMeanStrain && s.max_strain <= kTargetMaxStrain &&
         s.max_strain_p99 <= kTargetMaxStrainP99 &&
         s.penetration_max_mm.value_or(0.0) <= kTargetPenetrationMm && s.nan == 0 &&
         s.ms_per_frame_median <= budget &&
         (!self_collision || s.crossing_edges_max.value_or(0) == 0);
}

void PrintTable(const std::vector<json>& rows) {
  std::printf("\n| case | fabric | particles | ms median / p95 | max strain | p99 | mean | "
              "depth max / p99 [mm] | edges through | steps | meets |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|\n");
  int met = 0, measured = 0;
  for (const json& r : rows) {
    if (r.contains("error")) {
      std::printf("| %s | %s | – | refused: %s |||||||\n", r["case"].get<std::string>().c_str(),
                  r["fabric"].get<std::string>().c_str(), r["error"].get<std::string>().c_str());
      continue;
    }
    ++measured;
    const bool meets = r["meets_targets"].get<bool>();
    met += meets ? 1 : 0;
    const auto depth = [&](const char* key) {
      return r[key].is_null() ? std::string("–") : std::to_string(r[key].get<double>()).substr(0, 5);
    };
    std::printf("| %s | %s | %d | %.1f / %.1f | %.1f %% | %.1f %% | %.2f %% | %s / %s | %s | "
                "%.2f | %s |\n",
                r["case"].get<std::string>().c_str(), r["fabric"].get<std::string>().c_str(),
                r["particles"].get<int>(), r["ms_per_frame_median"].get<double>(),
                r["ms_per_frame_p95"].get<double>(), 100 * r["max_strain"].get<double>(),
                100 * r["max_strain_p99"].get<double>(), 100 * r["mean_strain"].get<double>(),
                depth("penetration_max_mm").c_str(), depth("penetration_p99_mm").c_str(),
                r["crossing_edges_max"].is_null()
                    ? "–"
                    : std::to_string(r["crossing_edges_max"].get<int>()).c_str(),
                r["steps_per_frame_mean"].get<double>(), meets ? "yes" : "no");
  }
  std::printf("\n%d of %d measured cases meet every target (mean |strain| <= %.0f %%, largest "
              "<= %.0f %%, p99 of the frames' largest <= %.0f %%, depth <= %.0f mm, no NaN, "
              "median frame within %.1f ms up to 3,000 particles, %.1f ms up to 10,000)\n",
              met, measured, 100 * kTargetMeanStrain, 100 * kTargetMaxStrain,
              100 * kTargetMaxStrainP99, kTargetPenetrationMm, kTargetMsSmall, kTargetMsLarge);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"garment_bench: garments x avatars x clips x fabric presets, measured every "
               "frame (docs/benchmarks.md)"};
  Options options;
  app.add_option("--data", options.data_dir, "Folder of the shared assets")->capture_default_str();
  app.add_option("--garments", options.garments,
                 "skirt, dress, cape (built in) and makehuman (every MakeHuman garment of the "
                 "data folder, on its own body)")
      ->capture_default_str();
  app.add_option("--avatars", options.avatars, "builtin, makehuman, cesiumman")
      ->capture_default_str();
  app.add_option("--avatar-file", options.avatar_files,
                 "More avatars: NAME=PATH (any file the importers read)");
  app.add_option("--clips", options.clips,
                 "Built-in clips (walk, run, kick, jump, dance) and file clips (cmu_walk, "
                 "cmu_kick, dm_walk, dm_run, dm_jump, dm_kick, dm_dance, mh_walk)")
      ->capture_default_str();
  app.add_option("--clip-file", options.clip_files, "More clips: NAME=PATH (BVH, DeepMimic, glTF, FBX)");
  app.add_option("--fabrics", options.fabrics, "Fabric presets")->capture_default_str();
  app.add_flag("--all-fabrics", options.all_fabrics,
               "Every case in every fabric (default: the fabrics in turn, one per case)");
  app.add_option("--seconds", options.seconds, "Seconds of the clip after the fit")
      ->check(CLI::Range(0.1, 60.0))
      ->capture_default_str();
  app.add_flag("--self-collision", options.self_collision, "Cloth against itself as well");
  app.add_option("--sheets", options.sheets, "Folder for the contact sheets ('' for none)")
      ->capture_default_str();
  app.add_option("--solver", options.solver,
                 "Overrides the engine's solver, to compare: pcg, multigrid, multigrid_galerkin")
      ->check(CLI::IsMember({"pcg", "multigrid", "multigrid_galerkin"}));
  app.add_option("--threads", options.threads, "Threads of the solver's loops")
      ->check(CLI::Range(1, sim::ThreadPool::kMaxThreads))->capture_default_str();
  app.add_option("--resolution", options.resolution,
                 "Built-in garments' particles around their circumference")
      ->check(CLI::Range(8, 1024))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::vector<json> rows;
  try {
    for (const std::string& f : options.fabrics) {
      if (!sim::FindFabricPreset(f)) throw sim::InputError("--fabrics: '" + f + "' is no preset");
    }
    if (!options.sheets.empty()) fs::create_directories(options.sheets);
    const std::vector<AvatarCase> avatars = LoadAvatars(options);
    const std::vector<GarmentCase> garments = ListGarments(options);
    const std::vector<ClipCase> clips = ListClips(options);
    std::size_t turn = 0;
    for (const ClipCase& clip_case : clips) {
      const auto clip = LoadClipCase(clip_case);
      for (const AvatarCase& avatar : avatars) {
        for (const GarmentCase& garment : garments) {
          if (!garment.pattern && !avatar.makehuman) continue;  // made for MakeHuman's body
          std::vector<std::string> fabrics = options.fabrics;
          if (!options.all_fabrics) fabrics = {options.fabrics[turn++ % options.fabrics.size()]};
          for (const std::string& fabric_name : fabrics) {
            const sim::FabricPreset& fabric = *sim::FindFabricPreset(fabric_name);
            const std::string id = garment.name + "/" + avatar.name + "/" + clip_case.name;
            json row = {{"case", id}, {"garment", garment.name}, {"avatar", avatar.name},
                        {"clip", clip_case.name}, {"fabric", fabric_name}};
            try {
              const CaseResult result =
                  RunCase(CaseScene(avatar, garment, clip, fabric, options),
                          id + "_" + fabric_name, options);
              row.update(result.row);
              row["meets_targets"] = MeetsTargets(result.summary, options.self_collision);
            } catch (const sim::InputError& error) {
              row["error"] = error.what();
            }
            std::cout << row.dump() << std::endl;
            rows.push_back(row);
          }
        }
      }
    }
  } catch (const sim::InputError& error) {
    std::cerr << "garment_bench: " << error.what() << "\n";
    return 1;
  }
  PrintTable(rows);
  return 0;
}
