/// @file
/// collision_bench: the garment scene of docs/BENCHMARKS.md — a garment on an avatar walking
/// (or playing another built-in clip, --clip) for 4 s after it has been fitted — once per collision method (paper §4), printing one JSON
/// object per run: collision and total ms per frame (medians), penetration of the cloth into
/// the true skinned mesh (not the collider's proxy), measured every frame with MeshDistance.
/// Avatars: the built-in humanoid, and the MakeHuman body from ../shared/data when present.
/// Single-threaded. The two methods run back to back in one process, so their ratio is
/// measured side by side on the same machine state. A last line gives the mesh method's
/// cloth-side adaptive regions' saving on a flat and on a folded sheet
/// (tools/regions_comparison.h, as collision_regions_bench).

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <vector>

#include "assets/clip_import.h"
#include "assets/makehuman_import.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/self_collision.h"
#include "sim_core/collision/superquadric_collider.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/garment_fit.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"
#include "tools/regions_comparison.h"

namespace {

using namespace costume;
using nlohmann::json;

struct Options {
  double walk_seconds = 4.0;
  std::string clip = "walk";
  int resolution = 64;
  std::string garment = "skirt";
  std::string data_dir = "../shared/data";
  std::string solver = "pcg";
  std::string makehuman_garment = "female_casualsuit02";
  bool makehuman = true;
  /// The collision methods run, in this order ("superquadric", "mesh"); the speed ratio is
  /// printed only when both run.
  std::vector<std::string> methods{"superquadric", "mesh"};
  /// Memory for the superquadric method's stored map drawings [MB] (0: draw every map).
  double superquadric_map_mb = sim::AvatarSpec{}.superquadric_map_mb;
  double max_skin_travel = sim::AvatarSpec{}.max_skin_travel;
  /// Calls per mode of the cloth-side regions' comparison (0: skip it).
  int regions_reps = 100;
  /// Cloth against itself as well (effects.self_collision).
  bool self_collision = false;
};

/// CPU time of the calling thread [ms]: unlike wall time, not stretched when other
/// processes share the cores (the build machine is shared).
double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

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
  spec.superquadric_map_mb = options.superquadric_map_mb;
  spec.max_skin_travel = options.max_skin_travel;
  scene.avatar = spec;
  scene.duration = spec.motion.fit_time + options.walk_seconds;
  scene.effects.self_collision = options.self_collision;
  sim::Material cotton;
  cotton.name = "skirt_cotton";
  cotton.density = 0.15;
  cotton.stretch_stiffness = cotton.shear_stiffness = 300.0;
  cotton.bending_rigidity = 5e-6;
  cotton.friction = 0.5;  // scenes/garment.toml's: on the skin's 0.5, contacts at 0.5
  scene.materials.push_back(cotton);
  sim::GarmentSpec garment;
  garment.name = options.garment;
  garment.material = cotton.name;
  garment.pattern = options.garment;
  garment.pattern_resolution = options.resolution;
  scene.garments.push_back(garment);
  return scene;
}

/// The MakeHuman garment from ../shared/data, fitted to the body by its .mhclo and then out
/// of the body (GarmentSpec::fit_outside_body), as a mesh garment whose waistband moves with
/// the avatar's pelvis (its lower torso when the skeleton has no pelvis of its own).
sim::SceneDescription MakeHumanGarmentScene(std::shared_ptr<const sim::Avatar> body,
                                            std::shared_ptr<const sim::Clip> clip,
                                            sim::BodyCollisionMethod method,
                                            const assets::ObjMesh& base_obj,
                                            const std::filesystem::path& mhclo, const Options& options) {
  sim::SceneDescription scene = GarmentScene(body, clip, method, options);
  sim::GarmentSpec garment =
      assets::MakeHumanGarmentSpec(mhclo.string(), base_obj, body->skeleton());
  garment.name = options.makehuman_garment;
  garment.material = scene.materials[0].name;
  scene.garments = {garment};
  return scene;
}

/// Memory the superquadric collider's stored map drawings use [MB] (0 for the mesh method).
double MapCacheMegabytes(const sim::Simulation& simulation) {
  const auto* collider = dynamic_cast<const sim::SuperquadricCollider*>(simulation.body_collider());
  return collider ? collider->map_cache_stats().bytes_used / 1048576.0 : 0.0;
}

/// The joint of `motion`'s skeleton nearest `x` (world) [m].
int NearestJoint(const sim::AvatarMotion& motion, const Eigen::Vector3d& x) {
  int nearest = 0;
  for (int j = 1; j < static_cast<int>(motion.joint_world().size()); ++j) {
    if ((motion.joint_world()[j].translation() - x).squaredNorm() <
        (motion.joint_world()[nearest].translation() - x).squaredNorm()) {
      nearest = j;
    }
  }
  return nearest;
}

/// The `count` keys with the largest counts as [key, count] pairs, most first.
json MostFrequent(const std::map<std::string, int>& counts, std::size_t count) {
  std::vector<std::pair<int, std::string>> sorted;
  for (const auto& [key, n] : counts) sorted.emplace_back(n, key);
  std::sort(sorted.rbegin(), sorted.rend());
  json top = json::array();
  for (std::size_t k = 0; k < std::min(count, sorted.size()); ++k) {
    top.push_back({sorted[k].second, sorted[k].first});
  }
  return top;
}

/// The least the superquadric test evaluates in one step: one inside-outside function for
/// each particle and each segment whose shell box (`SuperquadricSegment::shell_box`, the box
/// the collider culls with, in the superquadric's frame, without the allowance it adds for
/// the step's motion) holds it, at the step's end. No map, no response, none of the
/// collider's other work: a floor for any collider with these culls and this function,
/// measured to see how far the 20× lies from it.
struct FloorFigures {
  double ms = 0.0;  ///< per step [ms]
  long long pairs = 0;  ///< (particle, segment) pairs evaluated per step
  /// The same pairs handed over by a cull that costs nothing, each read from its map
  /// (ProbeFloor) [ms per step].
  double probe_ms = 0.0;
};

/// The floor's pairs as a cull that cost nothing would hand them over (listed before the
/// clock starts), each moved into its segment's frame and read from its map by the
/// collider's own ProbeShell: the paper's two steps (is the point inside, and deeper than
/// the mapped skin?) once per pair, with none of the collider's other work.
double ProbeFloor(const std::vector<sim::SuperquadricSegment>& segments,
                  const std::vector<Eigen::Isometry3d>& to_local, const sim::Points& x,
                  double thickness) {
  std::vector<std::pair<int, int>> pairs;  // particle, segment
  for (Eigen::Index p = 0; p < x.rows(); ++p) {
    const Eigen::Vector3d world = x.row(p).transpose();
    for (std::size_t s = 0; s < segments.size(); ++s) {
      if (segments[s].shell_box.contains(to_local[s] * world)) {
        pairs.emplace_back(static_cast<int>(p), static_cast<int>(s));
      }
    }
  }
  constexpr int kRepeats = 5;
  double sum = 0.0;
  sim::ShellProbe probe;
  const auto start = std::chrono::steady_clock::now();
  for (int r = 0; r < kRepeats; ++r) {
    for (const auto& [p, s] : pairs) {
      sim::ProbeShell(segments[s], to_local[s] * x.row(p).transpose(), thickness, probe);
      sum += probe.normal_gap;
    }
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  volatile double sink = sum;  // so the probes are not optimised away
  (void)sink;
  return ms / kRepeats;
}

FloorFigures SuperquadricFloor(const sim::SuperquadricCollider& collider, const sim::Points& x,
                               double thickness) {
  const auto& segments = collider.segments();
  std::vector<Eigen::Isometry3d> to_local(segments.size());
  constexpr int kRepeats = 5;  // the loop is short: repeated for a steadier clock
  FloorFigures floor;
  double sum = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (int r = 0; r < kRepeats; ++r) {
    for (std::size_t s = 0; s < segments.size(); ++s) {
      to_local[s] = collider.end_frame(static_cast<int>(s)).inverse();
    }
    long long pairs = 0;
    for (Eigen::Index p = 0; p < x.rows(); ++p) {
      const Eigen::Vector3d world = x.row(p).transpose();
      for (std::size_t s = 0; s < segments.size(); ++s) {
        const Eigen::Vector3d q = to_local[s] * world;
        if (!segments[s].shell_box.contains(q)) continue;
        sum += sim::InsideOutside(segments[s].superquadric, q);
        ++pairs;
      }
    }
    floor.pairs = pairs;
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  volatile double sink = sum;  // so the evaluations are not optimised away
  (void)sink;
  floor.ms = ms / kRepeats;
  floor.probe_ms = ProbeFloor(segments, to_local, x, thickness);
  return floor;
}

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

/// A rebuild of the scene as a server's STOP or a new fabric does it (with the ColliderMemo
/// the first build used): how long it takes, and the collision ms median over the clip's
/// first pass after it, which a new collider would draw afresh.
struct RebuildFigures {
  double build_ms = 0.0;
  double first_pass_collision_ms = 0.0;
};

RebuildFigures Rebuild(const sim::SceneDescription& scene, sim::ColliderMemo& memo,
                       int fit_frames, int first_pass_frames) {
  RebuildFigures figures;
  const auto start = std::chrono::steady_clock::now();
  auto simulation = sim::Simulation::Build(scene, nullptr, &memo);
  figures.build_ms = MsSince(start);
  std::vector<double> collision_ms;
  for (int f = 0; f < fit_frames + first_pass_frames; ++f) {
    const sim::FrameReport report = simulation->AdvanceFrame();
    if (f >= fit_frames) collision_ms.push_back(report.collision_ms);
  }
  figures.first_pass_collision_ms = Median(collision_ms);
  return figures;
}

/// Runs one scene and measures it; the penetration oracle is the skinned mesh itself.
json Measure(const std::string& avatar_name, const sim::SceneDescription& scene) {
  sim::ColliderMemo memo;
  const auto build_start = std::chrono::steady_clock::now();
  auto simulation = sim::Simulation::Build(scene, nullptr, &memo);
  const double build_ms = MsSince(build_start);
  const sim::AvatarMotion& motion = *simulation->avatar();
  sim::MeshDistance skin(avatar_name, motion.vertices(), motion.avatar().triangles());
  std::vector<bool> attached(simulation->model().num_particles(), false);
  for (const sim::BodyAttachment& a : simulation->attachments()) attached[a.particle] = true;

  std::vector<double> total_ms, collision_ms, update_ms, with_update_ms, cpu_ms, frame_max_depth,
      frame_max_strain, frame_mean_strain, self_collision_ms;
  double max_depth = 0.0, max_strain = 0.0;
  // Per joint, the frames whose most stretched spring is nearest it: where the collider
  // holds the cloth stretched.
  std::map<std::string, int> strain_near;
  // Where the deepest penetration was: the measured frame, the particle and the joint
  // nearest it, for finding what let it in.
  int deepest_frame = -1, deepest_particle = -1, deepest_joint = -1, max_strain_frame = -1;
  int rolled_back = 0, unconverged = 0, steps = 0, most_steps = 0;
  const int fit_frames = static_cast<int>(scene.avatar->motion.fit_time * scene.frame_rate);
  sim::Points cloth;
  // The first pass through the clip draws every map; later passes may reuse the drawings
  // (SuperquadricColliderOptions::map_cache_bytes), so it is reported apart.
  const auto& clip = scene.avatar->clip;
  const int first_pass_frames =
      clip ? std::max(1, static_cast<int>(std::lround(clip->duration() * scene.frame_rate))) : 0;
  long long maps_drawn = 0, maps_reused = 0, skin_checks = 0, winding_checks = 0, buried = 0,
            unresolved_self = 0, iterations = 0, contacts = 0;
  const auto* superquadrics =
      dynamic_cast<const sim::SuperquadricCollider*>(simulation->body_collider());
  std::vector<double> floor_ms, floor_pairs, probe_floor_ms;
  for (int f = 0; f < simulation->num_frames(); ++f) {
    const double cpu_start = ThreadCpuMs();
    const sim::FrameReport report = simulation->AdvanceFrame();
    const double cpu = ThreadCpuMs() - cpu_start;
    rolled_back += report.rolled_back_steps;
    unconverged += report.converged ? 0 : 1;
    if (f < fit_frames) continue;  // the clip is measured, not the fitting
    steps += report.steps;
    most_steps = std::max(most_steps, report.steps);
    iterations += report.iterations;
    contacts += report.num_contacts;
    maps_drawn += report.maps_drawn;
    maps_reused += report.maps_reused;
    skin_checks += report.skin_checks;
    winding_checks += report.winding_checks;
    buried += report.buried;
    total_ms.push_back(report.wall_ms);
    cpu_ms.push_back(cpu);
    collision_ms.push_back(report.collision_ms);
    update_ms.push_back(report.collision_update_ms);
    with_update_ms.push_back(report.collision_ms + report.collision_update_ms);
    self_collision_ms.push_back(report.self_collision_ms);
    unresolved_self += report.unresolved_self_collisions;
    if (superquadrics) {
      const FloorFigures floor = SuperquadricFloor(*superquadrics, simulation->state().positions,
                                                   scene.avatar->thickness);
      floor_ms.push_back(floor.ms * report.steps);
      probe_floor_ms.push_back(floor.probe_ms * report.steps);
      floor_pairs.push_back(static_cast<double>(floor.pairs));
    }
    skin.Update(motion.vertices());
    double deepest = 0.0;
    int deepest_here = -1;
    const sim::Points& x = simulation->state().positions;
    for (Eigen::Index p = 0; p < x.rows(); ++p) {
      if (attached[p]) continue;
      const double depth = skin.PenetrationDepth(x.row(p).transpose(), 0.1);
      if (depth > deepest) {
        deepest = depth;
        deepest_here = static_cast<int>(p);
      }
    }
    if (deepest_here >= 0 && deepest > max_depth) {
      deepest_frame = static_cast<int>(total_ms.size()) - 1;
      deepest_particle = deepest_here;
      deepest_joint = NearestJoint(motion, x.row(deepest_here).transpose());
    }
    frame_max_depth.push_back(std::max(0.0, deepest));
    max_depth = std::max(max_depth, deepest);
    const sim::StrainStats strain = sim::StructuralStrain(simulation->model(), x);
    frame_max_strain.push_back(strain.max);
    frame_mean_strain.push_back(strain.mean);
    if (strain.max > max_strain) max_strain_frame = static_cast<int>(total_ms.size()) - 1;
    max_strain = std::max(max_strain, strain.max);
    if (strain.max_spring >= 0) {
      const sim::Spring& spring = simulation->model().springs()[strain.max_spring];
      const Eigen::Vector3d middle = 0.5 * (x.row(spring.a) + x.row(spring.b)).transpose();
      ++strain_near[motion.avatar().skeleton().joint(NearestJoint(motion, middle)).name];
    }
  }
  // The measured frames in order: the clip's first pass, then the later passes.
  const std::ptrdiff_t first_pass =
      std::min<std::ptrdiff_t>(first_pass_frames, collision_ms.size());
  const std::vector<double> first_pass_collision_ms(collision_ms.begin(),
                                                    collision_ms.begin() + first_pass);
  const std::vector<double> later_passes_collision_ms(collision_ms.begin() + first_pass,
                                                      collision_ms.end());
  const std::vector<double> first_pass_total_ms(total_ms.begin(), total_ms.begin() + first_pass);
  const auto over_budget = std::count_if(total_ms.begin(), total_ms.end(),
                                         [](double ms) { return ms >= 1000.0 / 60.0; });
  const auto& s = scene.avatar.value();
  const int particles = simulation->model().num_particles();
  const int avatar_vertices = motion.avatar().num_vertices();
  const double map_cache_mb = MapCacheMegabytes(*simulation);
  const std::string deepest_near =
      deepest_joint < 0 ? "" : motion.avatar().skeleton().joint(deepest_joint).name;
  // Brute force over every edge and triangle: once, at the end, what self-collision (or
  // its absence) left.
  const int crossing_edges =
      sim::CountCrossingEdges(simulation->model(), simulation->state().positions);
  simulation.reset();  // only the last simulation built with the memo may step
  const RebuildFigures rebuilt = Rebuild(scene, memo, fit_frames, first_pass_frames);
  return {{"avatar", avatar_name},
          {"clip", s.clip ? s.clip->name : "none"},
          {"method", sim::BodyCollisionMethodName(s.collision)},
          {"garment", scene.garments[0].name},
          {"particles", particles},
          {"avatar_vertices", avatar_vertices},
          {"frames_measured", total_ms.size()},
          {"steps_per_frame_mean", total_ms.empty() ? 0.0 : double(steps) / total_ms.size()},
          {"steps_per_frame_max", most_steps},
          // What the solve's time follows: its iterations, and the particles it constrains.
          {"iterations_per_step_mean", steps ? double(iterations) / steps : 0.0},
          {"contacts_per_step_mean", steps ? double(contacts) / steps : 0.0},
          {"collision_ms_median", Median(collision_ms)},
          {"collision_ms_median_first_pass", Median(first_pass_collision_ms)},
          // The kick's first pass is 90 of the 240 frames of 4 s, so the median of all frames
          // lies among its frames, where every map is drawn; this one is the loop's steady
          // state.
          {"collision_ms_median_later_passes", Median(later_passes_collision_ms)},
          {"collision_update_ms_median", Median(update_ms)},
          // Superquadric method only (0 for the mesh method): SuperquadricFloor per frame.
          {"superquadric_floor_ms_median", Median(floor_ms)},
          {"superquadric_floor_pairs_per_step_median", Median(floor_pairs)},
          // The floor's pairs handed over by a cull that costs nothing, each read from its
          // map once (ProbeFloor).
          {"superquadric_probe_floor_ms_median", Median(probe_floor_ms)},
          {"collision_with_update_ms_median", Median(with_update_ms)},
          {"maps_drawn", maps_drawn},
          {"maps_reused", maps_reused},
          {"skin_checks", skin_checks},
          {"winding_checks", winding_checks},
          {"buried", buried},
          {"map_cache_mb", map_cache_mb},
          // Building the scene, and building it again as a server's STOP does (the
          // superquadric collider kept, sim_core/scene/body_colliders.h), with the collision
          // ms median over the clip's first pass after that rebuild.
          {"build_ms", build_ms},
          {"rebuild_ms", rebuilt.build_ms},
          {"collision_ms_median_first_pass_after_rebuild", rebuilt.first_pass_collision_ms},
          {"total_ms_median", Median(total_ms)},
          // The first pass draws every superquadric map: whether it keeps up with 60 Hz too,
          // and how many frames of the whole run did not.
          {"total_ms_median_first_pass", Median(first_pass_total_ms)},
          {"total_ms_p99", Percentile(total_ms, 0.99)},
          {"frames_over_60hz_budget", over_budget},
          {"total_cpu_ms_median", Median(cpu_ms)},
          {"faster_than_real_time_60hz", Median(total_ms) < 1000.0 / 60.0},
          {"penetration_max_mm", 1e3 * std::max(0.0, max_depth)},
          {"penetration_p99_mm", 1e3 * Percentile(frame_max_depth, 0.99)},
          {"penetration_max_frame", deepest_frame},
          {"max_strain_frame", max_strain_frame},
          {"penetration_max_particle", deepest_particle},
          {"penetration_max_near", deepest_near},
          {"max_strain", max_strain},
          // One spring in one frame sets the max; the frames' maxima's median and p99 say
          // whether the cloth stays stretched.
          {"max_strain_median", Median(frame_max_strain)},
          {"max_strain_p99", Percentile(frame_max_strain, 0.99)},
          {"max_strain_near", MostFrequent(strain_near, 3)},
          // The whole garment: each frame's mean |strain| over the structural springs, whose
          // median a few pinched springs do not set.
          {"mean_strain_median", Median(frame_mean_strain)},
          {"rolled_back_steps", rolled_back},
          {"self_collision", scene.effects.self_collision},
          {"self_collision_ms_median", Median(self_collision_ms)},
          {"unresolved_self_collisions", unresolved_self},
          {"crossing_edges_last_frame", crossing_edges},
          {"unconverged_frames", unconverged}};
}

/// Both methods on one avatar, side by side; `make_scene` builds the scene per method.
template <typename MakeScene>
void RunAvatar(const std::string& name, const std::vector<std::string>& methods,
               MakeScene make_scene) {
  json runs = json::array();
  for (const std::string& method_name : methods) {
    const sim::BodyCollisionMethod method = method_name == "mesh"
                                                ? sim::BodyCollisionMethod::kMesh
                                                : sim::BodyCollisionMethod::kSuperquadric;
    try {
      json run = Measure(name, make_scene(method));
      std::cout << run.dump() << std::endl;
      runs.push_back(run);
    } catch (const sim::InputError& error) {
      // A scene this program cannot run (an asset that needs repair) is reported, and the
      // other runs go on.
      std::cout << json{{"avatar", name}, {"method", sim::BodyCollisionMethodName(method)},
                        {"error", error.what()}}
                       .dump()
                << std::endl;
      return;
    }
  }
  if (runs.size() != 2) return;
  const double fast = runs[0]["collision_ms_median"], accurate = runs[1]["collision_ms_median"];
  // With each collider's per-step Update (the mesh method's refit) as well: the whole of
  // what each method costs a frame.
  const double fast_all = runs[0]["collision_with_update_ms_median"];
  const double accurate_all = runs[1]["collision_with_update_ms_median"];
  const double floor = runs[0]["superquadric_floor_ms_median"];
  const double probe = runs[0]["superquadric_probe_floor_ms_median"];
  const double fast_later = runs[0]["collision_ms_median_later_passes"];
  const double accurate_later = runs[1]["collision_ms_median_later_passes"];
  std::cout << json{{"avatar", name},
                    {"superquadric_speedup_over_mesh", fast > 0 ? accurate / fast : 0.0},
                    {"superquadric_speedup_over_mesh_with_update",
                     fast_all > 0 ? accurate_all / fast_all : 0.0},
                    {"superquadric_speedup_over_mesh_later_passes",
                     fast_later > 0 ? accurate_later / fast_later : 0.0},
                    // The most any superquadric test could gain: the mesh method against
                    // the least such a test must evaluate (SuperquadricFloor).
                    {"superquadric_floor_speedup_over_mesh", floor > 0 ? accurate / floor : 0.0},
                    // ... and against the paper's two steps once per pair, culled for free.
                    {"superquadric_probe_floor_speedup_over_mesh",
                     probe > 0 ? accurate / probe : 0.0},
                    {"target_speedup", 20.0},
                    {"target_penetration_mm", 2.0}}
                   .dump()
            << std::endl;
}

}  // namespace

/// Throws sim::InputError naming the garments there are when --makehuman-garment names none
/// of them (and the MakeHuman body is there to wear it).
void RequireMakeHumanGarment(const Options& options) {
  const std::filesystem::path clothes =
      std::filesystem::path(options.data_dir) / "makehuman" / "clothes";
  if (!options.makehuman || options.makehuman_garment == "none" ||
      !std::filesystem::is_directory(clothes) ||
      std::filesystem::exists(clothes / options.makehuman_garment /
                              (options.makehuman_garment + ".mhclo"))) {
    return;
  }
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(clothes)) {
    if (entry.is_directory()) names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  names.push_back("none");
  std::string allowed;
  for (const std::string& name : names) allowed += (allowed.empty() ? "" : ", ") + name;
  throw sim::InputError("--makehuman-garment '" + options.makehuman_garment + "': no " +
                        (clothes / options.makehuman_garment /
                         (options.makehuman_garment + ".mhclo")).string() +
                        "; allowed: " + allowed);
}

int main(int argc, char** argv) {
  CLI::App app{"collision_bench: the garment scene per collision method (docs/BENCHMARKS.md)"};
  Options options;
  app.add_option("--walk", options.walk_seconds, "Seconds of the clip measured after fitting")
      ->check(CLI::Range(0.1, 60.0))
      ->capture_default_str();
  app.add_option("--clip", options.clip,
                 "Built-in clip the avatar plays (retargeted onto MakeHuman)")
      ->check(CLI::IsMember(sim::BuiltInClipNames()))
      ->capture_default_str();
  app.add_option("--resolution", options.resolution, "Garment particles around its circumference")
      ->check(CLI::Range(8, 1024))
      ->capture_default_str();
  app.add_option("--garment", options.garment, "Built-in garment")
      ->check(CLI::IsMember({"skirt", "dress", "cape"}))
      ->capture_default_str();
  app.add_option("--solver", options.solver, "Cloth solver")
      ->check(CLI::IsMember({"pcg", "multigrid"}))
      ->capture_default_str();
  app.add_option("--data", options.data_dir, "Folder of the shared assets (MakeHuman)")
      ->capture_default_str();
  app.add_option("--makehuman-garment", options.makehuman_garment,
                 "MakeHuman garment folder under makehuman/clothes ('none': only the skirt on MakeHuman)")
      ->capture_default_str();
  app.add_option("--methods", options.methods,
                 "Collision methods to run, in order (the speed ratio needs both)")
      ->check(CLI::IsMember({"superquadric", "mesh"}))
      ->capture_default_str();
  app.add_option("--superquadric-map-mb", options.superquadric_map_mb,
                 "Memory for the superquadric method's stored map drawings, reused when the "
                 "skin comes back (0: draw every map every frame)")
      ->check(CLI::Range(0.0, sim::kMaxSuperquadricMapMb))
      ->capture_default_str();
  app.add_option("--max-skin-travel", options.max_skin_travel,
                 "Farthest the skin near the cloth may move in one step before a frame is split "
                 "into more steps [m] (0: never split)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_flag("!--no-makehuman", options.makehuman, "Skip the MakeHuman body");
  app.add_flag("--self-collision", options.self_collision,
               "Cloth against itself as well (effects.self_collision; off costs nothing)");
  app.add_option("--regions-reps", options.regions_reps,
                 "Calls per mode of the adaptive regions' comparison on a flat and a folded "
                 "sheet (as collision_regions_bench; 0: skip)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    RequireMakeHumanGarment(options);  // a typo found now, not after minutes of runs
    auto humanoid = sim::MakeHumanoid();
    auto clip = std::make_shared<const sim::Clip>(
        sim::MakeBuiltInClip(options.clip, humanoid->shared_skeleton()));
    RunAvatar("builtin humanoid", options.methods, [&](sim::BodyCollisionMethod method) {
      return GarmentScene(humanoid, clip, method, options);
    });
    const std::filesystem::path mh = std::filesystem::path(options.data_dir) / "makehuman";
    if (options.makehuman && std::filesystem::exists(mh / "body" / "base.obj")) {
      auto body = assets::LoadMakeHumanAvatar((mh / "body" / "base.obj").string(),
                                              (mh / "body" / "default.mhskel").string(),
                                              (mh / "body" / "default_weights.mhw").string());
      RunAvatar("makehuman", options.methods, [&](sim::BodyCollisionMethod method) {
        return GarmentScene(body, clip, method, options);
      });
      if (options.makehuman_garment != "none") {
        const std::filesystem::path mhclo = mh / "clothes" / options.makehuman_garment /
                                            (options.makehuman_garment + ".mhclo");
        const assets::ObjMesh base_obj = assets::ReadObj((mh / "body" / "base.obj").string());
        RunAvatar("makehuman + " + options.makehuman_garment, options.methods,
                  [&](sim::BodyCollisionMethod method) {
                    return MakeHumanGarmentScene(body, clip, method, base_obj, mhclo, options);
                  });
      }
    } else if (options.makehuman) {
      std::cerr << "MakeHuman body not found under " << mh << "; skipped\n";
    }
    if (options.regions_reps > 0) {
      tools::RegionsComparisonSettings regions;
      regions.reps = options.regions_reps;
      std::cout << json{{"adaptive_regions", tools::CompareClothRegions(regions)}}.dump()
                << std::endl;
    }
  } catch (const sim::InputError& error) {
    std::cerr << "collision_bench: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
