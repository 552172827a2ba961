/// @file
/// costume_sim: runs a scene (a TOML file, or a built-in one) headless. Prints progress and
/// per-frame timings and writes the cloth's frames as OBJ files.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>
#include <vector>

#include "assets/frame_writer.h"
#include "assets/run_summary_json.h"
#include "assets/scene_file.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/garment_metrics.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"

namespace {

using costume::sim::FrameReport;
using costume::sim::Simulation;

struct Options {
  std::string scene_file;
  std::string builtin = "garment";
  std::string out_dir = "out";
  bool write_frames = true;
  bool quiet = false;
  /// Measure every frame (garment_metrics.h) and end with one JSON line of the run's figures.
  bool json = false;
  double duration = 0.0;
  /// Overrides of the scene's collision method and self-collision switch ("" keeps them).
  std::string collision;
  std::string self_collision;
  /// Overrides solver.threads (-1 keeps the scene's).
  int threads = -1;
};

costume::sim::SceneDescription LoadScene(const Options& options) {
  if (!options.scene_file.empty()) return costume::assets::LoadSceneFile(options.scene_file);
  return costume::assets::LoadBuiltInScene(options.builtin);
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void PrintFrame(int frame, int num_frames, const Simulation& sim, const FrameReport& r) {
  char extra[128] = "";
  if (sim.body_collider()) {
    std::snprintf(extra, sizeof(extra),
                  "  avatar collision %5.2f ms (+%4.2f ms following the body)", r.collision_ms,
                  r.collision_update_ms);
  }
  if (sim.scene().effects.self_collision) {
    const std::size_t used = std::strlen(extra);
    std::snprintf(extra + used, sizeof(extra) - used, "  self-collision %5.2f ms%s",
                  r.self_collision_ms, r.unresolved_self_collisions ? " [unresolved]" : "");
  }
  char split[64] = "";
  if (r.steps > sim.scene().solver.substeps) {
    // avatar.max_skin_travel: the skin near the cloth moved too far for the usual steps.
    std::snprintf(split, sizeof(split), "  [%d steps: fast skin]", r.steps);
  }
  std::printf("frame %4d/%d  t=%6.3f s  %7.2f ms  iterations %4d  contacts %5d%s%s%s%s\n", frame,
              num_frames, sim.state().time, r.wall_ms, r.iterations, r.num_contacts, extra, split,
              r.converged ? "" : "  [solver hit its iteration cap]",
              r.rolled_back_steps ? "  [non-finite step undone]" : "");
}

/// The command line's overrides of how cloth collides (CollisionSettings, as the GUI's
/// Collision tab sets them).
void ApplyCollisionOverrides(const Options& options, costume::sim::SceneDescription& scene) {
  costume::sim::CollisionSettings settings = costume::sim::CollisionSettingsOf(scene);
  if (!options.collision.empty()) {
    if (!scene.avatar) {
      throw costume::sim::InputError(scene.source + ": --collision " + options.collision +
                                     ": the scene has no avatar to collide with");
    }
    settings.method = options.collision == "mesh" ? costume::sim::BodyCollisionMethod::kMesh
                                                  : costume::sim::BodyCollisionMethod::kSuperquadric;
  }
  if (!options.self_collision.empty()) settings.self_collision = options.self_collision == "on";
  costume::sim::ApplyCollisionSettings(settings, scene);
}

const char* CollisionName(const costume::sim::SceneDescription& scene) {
  return scene.avatar ? costume::sim::BodyCollisionMethodName(scene.avatar->collision) : "none";
}

/// Creates the folder the frames go to, or throws InputError naming it, --out and why.
/// The scene's name as one folder name: a name is free text ("../../x", "a/b") and must not
/// put the frames outside --out, so separators and control characters become '_', as does a
/// name that is empty, "." or "..".
std::string FramesFolderName(const std::string& name) {
  std::string folder = name;
  for (char& c : folder) {
    if (c == '/' || c == '\\' || static_cast<unsigned char>(c) < 0x20) c = '_';
  }
  if (folder.empty() || folder == "." || folder == "..") folder = "_" + folder;
  return folder;
}

void MakeFramesFolder(const std::filesystem::path& out) {
  std::error_code error;
  std::filesystem::create_directories(out, error);
  if (error) {
    throw costume::sim::InputError("--out: cannot create the frames' folder '" + out.string() +
                                   "': " + error.message() + " (--no-frames writes none)");
  }
}

int Run(const Options& options) {
  costume::sim::SceneDescription scene = LoadScene(options);
  if (options.duration > 0) scene.duration = options.duration;
  ApplyCollisionOverrides(options, scene);
  if (options.threads >= 0) scene.solver.threads = options.threads;
  const std::filesystem::path out =
      std::filesystem::path(options.out_dir) / FramesFolderName(scene.name);
  if (options.write_frames) MakeFramesFolder(out);  // before a build that may take a while
  std::printf("scene '%s' (%s): building...\n", scene.name.c_str(), scene.source.c_str());
  auto sim = Simulation::Build(scene);
  const int num_frames = sim->num_frames();
  std::printf("%d particles, %d springs, %d frames at %.0f Hz, solver %s on %d thread(s), "
              "%d substep(s), avatar collision %s, self-collision %s\n",
              sim->model().num_particles(), sim->model().num_springs(), num_frames,
              scene.frame_rate, costume::sim::SolverMethodName(scene.solver.method),
              costume::sim::SolverThreads(scene.solver.threads), scene.solver.substeps,
              CollisionName(scene),
              scene.effects.self_collision ? "on" : "off");
  if (scene.avatar && scene.avatar->clip) {
    std::printf("%s\n", costume::sim::DescribeArmSpread(sim->arm_spread()).c_str());
  }
  std::vector<double> frame_ms, collision_ms;
  int rolled_back = 0;
  std::optional<costume::sim::GarmentMetrics> metrics;
  if (options.json) metrics.emplace(*sim);
  for (int frame = 1; frame <= num_frames; ++frame) {
    const FrameReport report = sim->AdvanceFrame();
    if (metrics) metrics->AddFrame(*sim, report);
    frame_ms.push_back(report.wall_ms);
    collision_ms.push_back(report.collision_ms + report.collision_update_ms);
    rolled_back += report.rolled_back_steps;
    if (!options.quiet) PrintFrame(frame, num_frames, *sim, report);
    if (options.write_frames) {
      char name[32];
      std::snprintf(name, sizeof(name), "frame_%04d.obj", frame);
      costume::assets::WriteObjFrame(out / name, sim->model(), sim->state().positions,
                                     sim->garments(), sim->avatar());
    }
  }
  const auto strain = costume::sim::StructuralStrain(sim->model(), sim->state().positions);
  char collision[64] = "";
  if (sim->body_collider()) {
    std::snprintf(collision, sizeof(collision), " (avatar collision %.2f)", Median(collision_ms));
  }
  // The last frame's figures; --json measures every frame (its max_strain is of any frame).
  std::printf("done: median %.2f ms/frame%s; last frame: largest strain %.2f%%, mean |strain| "
              "%.3f%%%s\n",
              Median(frame_ms), collision, 100 * strain.max, 100 * strain.mean,
              rolled_back ? ", some steps undone (see above)" : "");
  if (options.write_frames) std::printf("frames written to %s/frame_*.obj\n", out.c_str());
  if (metrics) std::printf("%s\n", costume::assets::RunSummaryJson(metrics->Summary()).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "costume_sim: simulates a cloth scene headless and writes its frames as OBJ files.\n"
      "Without a scene file it runs the built-in garment scene (a skirt on the walking\n"
      "built-in humanoid). Scene format: docs/scene_format.md."};
  Options options;
  app.add_option("scene", options.scene_file, "Scene file (TOML)")->check(CLI::ExistingFile);
  app.add_option("--builtin", options.builtin, "Built-in scene to run when no file is given")
      ->check(CLI::IsMember(costume::assets::BuiltInSceneNames()))
      ->capture_default_str();
  app.add_option("--out", options.out_dir, "Folder for the frames (a subfolder per scene)")
      ->capture_default_str();
  app.add_option("--duration", options.duration,
                 "Override the scene's duration [s] (0: keep the scene's own)")
      ->check(CLI::Range(0.0, 3600.0));
  app.add_flag("!--no-frames", options.write_frames, "Do not write OBJ frames");
  app.add_flag("--quiet", options.quiet, "Print only the summary");
  app.add_flag("--json", options.json,
               "Measure every frame (strain, depth inside the true skin, edges through the "
               "cloth) and end with one JSON line of the run's figures (docs/benchmarks.md)");
  app.add_option("--collision", options.collision,
                 "Override the avatar's collision method: superquadric (fast on a looping "
                 "clip's later passes) or mesh (accurate; docs/collision.md)")
      ->check(CLI::IsMember({"superquadric", "mesh"}));
  app.add_option("--self-collision", options.self_collision,
                 "Override the scene's self-collision (off costs nothing)")
      ->check(CLI::IsMember({"on", "off"}));
  app.add_option("--threads", options.threads,
                 "Override the scene's solver.threads (0: the machine's; any count gives the "
                 "same result)")
      ->check(CLI::Range(0, costume::sim::ThreadPool::kMaxThreads));
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(options);
  } catch (const costume::sim::InputError& error) {
    std::fprintf(stderr, "error: %s\n", error.what());
    return 2;
  } catch (const std::filesystem::filesystem_error& error) {
    std::fprintf(stderr, "error: %s\n", error.what());
    return 2;
  }
}
