/// @file
/// collision_bench: the garment scene of docs/BENCHMARKS.md — a garment on an avatar walking
/// for 4 s after it has been fitted — once per collision method (paper §4), printing one JSON
/// object per run: collision and total ms per frame (medians), penetration of the cloth into
/// the true skinned mesh (not the collider's proxy), measured every frame with MeshDistance.
/// Avatars: the built-in humanoid, and the MakeHuman body from ../shared/data when present.
/// Single-threaded. The two methods run back to back in one process, so their ratio is
/// measured side by side on the same machine state.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <vector>

#include "assets/clip_import.h"
#include "assets/makehuman_import.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"

namespace {

using namespace costume;
using nlohmann::json;

struct Options {
  double walk_seconds = 4.0;
  int resolution = 64;
  std::string garment = "skirt";
  std::string data_dir = "../shared/data";
  std::string solver = "multigrid";
  bool makehuman = true;
};

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(p * values.size()))];
}

sim::SceneDescription GarmentScene(std::shared_ptr<const sim::Avatar> avatar,
                                   std::shared_ptr<const sim::Clip> clip,
                                   sim::BodyCollisionMethod method, const Options& options) {
  sim::SceneDescription scene;
  scene.name = "garment";
  scene.source = "collision_bench";
  scene.solver.method = options.solver == "pcg" ? sim::SolverMethod::kPcg : sim::SolverMethod::kMultigrid;
  sim::AvatarSpec spec;
  spec.avatar = std::move(avatar);
  spec.clip = std::move(clip);
  spec.collision = method;
  scene.avatar = spec;
  scene.duration = spec.motion.fit_time + options.walk_seconds;
  sim::Material cotton;
  cotton.name = "skirt_cotton";
  cotton.density = 0.15;
  cotton.stretch_stiffness = cotton.shear_stiffness = 300.0;
  cotton.bending_rigidity = 5e-6;
  scene.materials.push_back(cotton);
  sim::GarmentSpec garment;
  garment.name = options.garment;
  garment.material = cotton.name;
  garment.pattern = options.garment;
  garment.pattern_resolution = options.resolution;
  scene.garments.push_back(garment);
  return scene;
}

/// Runs one scene and measures it; the penetration oracle is the skinned mesh itself.
json Measure(const std::string& avatar_name, const sim::SceneDescription& scene) {
  auto simulation = sim::Simulation::Build(scene);
  const sim::AvatarMotion& motion = *simulation->avatar();
  sim::MeshDistance skin(avatar_name, motion.vertices(), motion.avatar().triangles());
  std::vector<bool> attached(simulation->model().num_particles(), false);
  for (const sim::BodyAttachment& a : simulation->attachments()) attached[a.particle] = true;

  std::vector<double> total_ms, collision_ms, frame_max_depth;
  double max_depth = 0.0, max_strain = 0.0;
  int rolled_back = 0, unconverged = 0;
  const int fit_frames = static_cast<int>(scene.avatar->motion.fit_time * scene.frame_rate);
  sim::Points cloth;
  for (int f = 0; f < simulation->num_frames(); ++f) {
    const sim::FrameReport report = simulation->AdvanceFrame();
    rolled_back += report.rolled_back_steps;
    unconverged += report.converged ? 0 : 1;
    if (f < fit_frames) continue;  // the walk is measured, not the fitting
    total_ms.push_back(report.wall_ms);
    collision_ms.push_back(report.collision_ms);
    skin.Update(motion.vertices());
    double deepest = 0.0;
    const sim::Points& x = simulation->state().positions;
    for (Eigen::Index p = 0; p < x.rows(); ++p) {
      if (attached[p]) continue;
      deepest = std::max(deepest, -skin.SignedDistance(x.row(p).transpose(), 0.1));
    }
    frame_max_depth.push_back(std::max(0.0, deepest));
    max_depth = std::max(max_depth, deepest);
    max_strain = std::max(max_strain, sim::StructuralStrain(simulation->model(), x).max);
  }
  const auto& s = scene.avatar.value();
  return {{"avatar", avatar_name},
          {"clip", s.clip ? s.clip->name : "none"},
          {"method", sim::BodyCollisionMethodName(s.collision)},
          {"garment", scene.garments[0].name},
          {"particles", simulation->model().num_particles()},
          {"avatar_vertices", motion.avatar().num_vertices()},
          {"frames_measured", total_ms.size()},
          {"collision_ms_median", Median(collision_ms)},
          {"total_ms_median", Median(total_ms)},
          {"faster_than_real_time_60hz", Median(total_ms) < 1000.0 / 60.0},
          {"penetration_max_mm", 1e3 * std::max(0.0, max_depth)},
          {"penetration_p99_mm", 1e3 * Percentile(frame_max_depth, 0.99)},
          {"max_strain", max_strain},
          {"rolled_back_steps", rolled_back},
          {"unconverged_frames", unconverged}};
}

void RunAvatar(const std::string& name, std::shared_ptr<const sim::Avatar> avatar,
               std::shared_ptr<const sim::Clip> clip, const Options& options) {
  json runs = json::array();
  for (auto method : {sim::BodyCollisionMethod::kSuperquadric, sim::BodyCollisionMethod::kMesh}) {
    json run = Measure(name, GarmentScene(avatar, clip, method, options));
    std::cout << run.dump() << std::endl;
    runs.push_back(run);
  }
  const double fast = runs[0]["collision_ms_median"], accurate = runs[1]["collision_ms_median"];
  std::cout << json{{"avatar", name},
                    {"superquadric_speedup_over_mesh", fast > 0 ? accurate / fast : 0.0},
                    {"target_speedup", 20.0},
                    {"target_penetration_mm", 2.0}}
                   .dump()
            << std::endl;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"collision_bench: the garment scene per collision method (docs/BENCHMARKS.md)"};
  Options options;
  app.add_option("--walk", options.walk_seconds, "Seconds of walking measured after fitting")
      ->check(CLI::Range(0.1, 60.0));
  app.add_option("--resolution", options.resolution, "Garment particles around its circumference")
      ->check(CLI::Range(8, 1024));
  app.add_option("--garment", options.garment, "Built-in garment")
      ->check(CLI::IsMember({"skirt", "dress", "cape"}));
  app.add_option("--solver", options.solver, "Cloth solver")->check(CLI::IsMember({"pcg", "multigrid"}));
  app.add_option("--data", options.data_dir, "Folder of the shared assets (MakeHuman)");
  app.add_flag("!--no-makehuman", options.makehuman, "Skip the MakeHuman body");
  CLI11_PARSE(app, argc, argv);
  try {
    auto humanoid = sim::MakeHumanoid();
    auto walk = std::make_shared<const sim::Clip>(
        sim::MakeBuiltInClip("walk", humanoid->shared_skeleton()));
    RunAvatar("builtin humanoid", humanoid, walk, options);
    const std::filesystem::path mh = std::filesystem::path(options.data_dir) / "makehuman";
    if (options.makehuman && std::filesystem::exists(mh / "body" / "base.obj")) {
      auto body = assets::LoadMakeHumanAvatar((mh / "body" / "base.obj").string(),
                                              (mh / "body" / "default.mhskel").string(),
                                              (mh / "body" / "default_weights.mhw").string());
      RunAvatar("makehuman", body, walk, options);
    } else if (options.makehuman) {
      std::cerr << "MakeHuman body not found under " << mh << "; skipped\n";
    }
  } catch (const sim::InputError& error) {
    std::cerr << "collision_bench: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
