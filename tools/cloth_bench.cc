/// @file
/// cloth_bench: the hang and drape scenes of docs/BENCHMARKS.md, one JSON object per run,
/// with the peers' figures (measured on the same kind of machine) beside ours.
/// One thread unless --threads or a solver's threads= asks for more; medians over the run's
/// frames. The solvers of one scene, material and N
/// run side by side, frame by frame, and the later ones report their speed-up over the first.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <time.h>
#include <vector>

#include "assets/scene_file.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"

namespace {

using costume::sim::SceneDescription;
using costume::sim::Simulation;
using costume::sim::SolverMethod;
using nlohmann::json;

struct Run {
  /// `solver` is the method's name (or multigrid_galerkin / multigrid_rediscretised); `label`
  /// the whole --solver spec as given, naming the run in the output.
  std::string scene, material, solver, label;
  int n = 33;
  double dt = 1.0 / 60.0;
  double tolerance = 1e-2;
  int max_iterations = 1000;
  int frames = 120;
  double strain_limit = 0.1;
  int levels = 0;
  bool per_frame = false;
  bool own_error = false;
  int threads = 1;
};

/// The frame at which --own-error compares a run with CHOLMOD: t = 1 s at 60 frames a second
/// (the run's last frame when it is shorter).
int OwnErrorFrame(const Run& run) { return std::min(run.frames, 60); }

/// A peer's figure from docs/BENCHMARKS.md: ms per frame and max strain.
struct Peer {
  const char* name;
  const char* scene;
  const char* material;
  int n;
  double ms;
  double max_strain;
};

// Blender ran its Cotton preset, Bullet a k = 1000 N/m-like stiff sheet; docs/BENCHMARKS.md.
constexpr Peer kPeers[] = {
    {"bullet", "hang", "stiff_cotton", 65, 16.5, 0.079},
    {"bullet", "hang", "stiff_cotton", 129, 71.0, 1.08},
    {"bullet", "drape", "stiff_cotton", 65, 10.8, 0.146},
    {"bullet", "drape", "stiff_cotton", 129, 52.0, 0.28},
    {"blender", "hang", "blender_cotton", 33, 10.4, 0.051},
    {"blender", "hang", "blender_cotton", 65, 87.0, 0.18},
    {"blender", "hang", "blender_cotton", 129, 415.0, 0.59},
    {"blender", "drape", "blender_cotton", 65, 613.0, 0.055},
    {"blender", "drape", "blender_cotton", 129, 2232.0, 0.10},
};

SolverMethod MethodNamed(const std::string& name) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kHierarchical,
                              SolverMethod::kMultigrid, SolverMethod::kDirect}) {
    if (name == costume::sim::SolverMethodName(method)) return method;
  }
  return SolverMethod::kPcg;
}

/// Steps per 1/60 s frame for a step of dt [s].
int SubstepsOf(double dt) {
  return std::max(1, static_cast<int>(std::lround(1.0 / (60.0 * dt))));
}

constexpr const char* kSolverNames[] = {"pcg", "hierarchical", "multigrid", "multigrid_galerkin",
                                        "multigrid_rediscretised", "direct"};

/// Applies a --solver spec "NAME[,tol=T][,levels=L][,substeps=S]" to `run` (whose other
/// settings are the command line's). Throws InputError naming the spec and the allowed values.
void ApplySolverSpec(const std::string& spec, Run& run) {
  run.label = spec;
  std::stringstream parts(spec);
  std::string part;
  std::getline(parts, part, ',');
  if (std::find(std::begin(kSolverNames), std::end(kSolverNames), part) == std::end(kSolverNames)) {
    throw costume::sim::InputError("--solver '" + spec + "': unknown solver '" + part +
                                   "' (allowed: pcg, hierarchical, multigrid, "
                                   "multigrid_galerkin, multigrid_rediscretised, direct)");
  }
  run.solver = part;
  while (std::getline(parts, part, ',')) {
    const auto equals = part.find('=');
    const std::string key = part.substr(0, equals);
    const std::string text = equals == std::string::npos ? "" : part.substr(equals + 1);
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    const bool is_number =
        !text.empty() && end == text.c_str() + text.size() && std::isfinite(value);
    if (key == "tol" && is_number && value >= 1e-14 && value <= 0.999) {
      run.tolerance = value;
    } else if (key == "levels" && is_number && value == std::floor(value) && value >= 0 &&
               value <= 16) {
      run.levels = static_cast<int>(value);
    } else if (key == "substeps" && is_number && value == std::floor(value) && value >= 1 &&
               value <= 256) {
      run.dt = 1.0 / (60.0 * value);
    } else if (key == "threads" && is_number && value == std::floor(value) && value >= 1 &&
               value <= costume::sim::ThreadPool::kMaxThreads) {
      run.threads = static_cast<int>(value);
    } else {
      throw costume::sim::InputError(
          "--solver '" + spec + "': bad setting '" + part +
          "' (allowed: tol=1e-14..0.999, levels=0..16 (0 = all), substeps=1..256, threads=1..64)");
    }
  }
}

SceneDescription MakeScene(const Run& run) {
  SceneDescription scene = costume::assets::LoadBuiltInScene(run.scene);
  auto& garment = scene.garments.at(0);
  garment.panel->cols = garment.panel->rows = run.n;
  garment.material = run.material;
  scene.solver.method = MethodNamed(run.solver);
  // "multigrid_galerkin" / "multigrid_rediscretised": the V-cycle's coarse operators named
  // ("multigrid" takes the scene's, rediscretised by default).
  if (run.solver == "multigrid_galerkin" || run.solver == "multigrid_rediscretised") {
    scene.solver.method = SolverMethod::kMultigrid;
    scene.solver.coarse_operator = run.solver == "multigrid_galerkin"
                                       ? costume::sim::CoarseOperator::kGalerkin
                                       : costume::sim::CoarseOperator::kRediscretised;
  }
  scene.solver.levels = run.levels;
  scene.solver.tolerance = run.tolerance;
  scene.solver.max_iterations = run.max_iterations;
  scene.solver.strain_limit = run.strain_limit;
  scene.solver.substeps = SubstepsOf(run.dt);
  scene.solver.threads = run.threads;
  scene.frame_rate = 60.0;
  scene.duration = run.frames / 60.0;
  return scene;
}

double MinSphereDistance(const Simulation& sim) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& sphere : sim.scene().spheres) {
    for (Eigen::Index i = 0; i < sim.state().positions.rows(); ++i) {
      best = std::min(best, (sim.state().positions.row(i).transpose() - sphere.center).norm());
    }
  }
  return best;
}

/// CPU time of this thread [ms]: unlike wall time, it does not count the time other
/// processes held the core, so a busy shared machine inflates it much less (it still feels
/// their use of the shared caches and memory).
double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

/// One configuration's simulation and what its frames measured.
struct Measurement {
  Run run;
  SceneDescription scene;
  std::unique_ptr<Simulation> sim;
  std::vector<double> ms, cpu_ms;
  std::vector<int> frame_iterations;
  /// Positions after OwnErrorFrame(run) frames (--own-error).
  Eigen::MatrixXd compared_positions;
  long iterations = 0, coarse_iterations = 0, unconverged = 0, rolled_back = 0;
  long strain_corrections = 0;
  double min_distance = std::numeric_limits<double>::infinity(), penetration = 0.0;

  explicit Measurement(const Run& r) : run(r), scene(MakeScene(r)), sim(Simulation::Build(scene)) {}

  void AdvanceFrame() {
    const double cpu_start = ThreadCpuMs();
    const auto report = sim->AdvanceFrame();
    cpu_ms.push_back(ThreadCpuMs() - cpu_start);
    ms.push_back(report.wall_ms);
    frame_iterations.push_back(report.iterations);
    iterations += report.iterations;
    coarse_iterations += report.coarse_iterations;
    unconverged += report.converged ? 0 : 1;
    rolled_back += report.rolled_back_steps;
    strain_corrections += report.strain_corrections;
    penetration = std::max(penetration, report.max_penetration);
    min_distance = std::min(min_distance, MinSphereDistance(*sim));
    if (static_cast<int>(ms.size()) == OwnErrorFrame(run)) compared_positions = sim->state().positions;
  }

  json Report() const {
    const auto& x = sim->state().positions;
    const auto strain = costume::sim::StructuralStrain(sim->model(), x);
    const double frames = static_cast<double>(run.frames);
    json out = {{"scene", run.scene},
                {"material", run.material},
                {"n", run.n},
                {"solver", run.label},
                {"dt", sim->step()},
                {"substeps", scene.solver.substeps},
                {"threads", scene.solver.threads},
                {"levels", sim->pyramid() ? sim->pyramid()->num_levels() : 1},
                {"tolerance", run.tolerance},
                {"strain_limit", run.strain_limit},
                {"frames", run.frames},
                {"ms_per_frame_median", Median(ms)},
                {"ms_per_frame_max", *std::max_element(ms.begin(), ms.end())},
                {"cpu_ms_per_frame_median", Median(cpu_ms)},
                {"iterations_per_frame", static_cast<double>(iterations) / frames},
                {"coarse_iterations_per_frame", static_cast<double>(coarse_iterations) / frames},
                {"frames_unconverged", unconverged},
                {"steps_rolled_back", rolled_back},
                {"strain_corrections", strain_corrections},
                {"max_strain", strain.max},
                {"mean_strain", strain.mean},
                {"nan", !x.allFinite()}};
    if (run.per_frame) out["iterations_each_frame"] = frame_iterations;
    if (!scene.spheres.empty()) {
      out["min_sphere_distance"] = min_distance;
      out["sphere_radius"] = scene.spheres[0].radius;
      out["max_shell_penetration_before_projection"] = penetration;
    }
    for (const Peer& peer : kPeers) {
      if (run.scene == peer.scene && run.material == peer.material && run.n == peer.n) {
        out[std::string(peer.name) + "_ms"] = peer.ms;
        out[std::string(peer.name) + "_max_strain"] = peer.max_strain;
        out[std::string("speedup_vs_") + peer.name] = peer.ms / Median(ms);
      }
    }
    return out;
  }
};

/// Positions of `run`'s scene solved by CHOLMOD at the run's step and substeps, after
/// OwnErrorFrame(run) frames: the exact solution of every step's linear system, so that a run's
/// distance from it is its solver's own error and not the time step's.
Eigen::MatrixXd DirectSolverPositions(const Run& run) {
  Run reference = run;
  reference.solver = "direct";
  reference.label = "direct";
  reference.frames = OwnErrorFrame(run);
  reference.threads = 1;  // CHOLMOD's result does not depend on it
  Measurement m(reference);
  for (int f = 0; f < reference.frames; ++f) m.sim->AdvanceFrame();
  return m.sim->state().positions;
}

/// RMS over particles of the distance between two position sets [mm].
double RmsDistanceMm(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return 1e3 * std::sqrt((a - b).rowwise().squaredNorm().mean());
}

/// Adds own_error_rms_mm to `out`: `m`'s distance from CHOLMOD at the same step (one
/// reference run per step size, kept in `references`).
void AddOwnError(const Measurement& m, std::vector<std::pair<double, Eigen::MatrixXd>>& references,
                 json& out) {
  auto found = std::find_if(references.begin(), references.end(),
                            [&](const auto& r) { return r.first == m.run.dt; });
  if (found == references.end()) {
    references.emplace_back(m.run.dt, DirectSolverPositions(m.run));
    found = references.end() - 1;
  }
  out["own_error_rms_mm"] = RmsDistanceMm(m.compared_positions, found->second);
  out["own_error_at_s"] = OwnErrorFrame(m.run) / 60.0;
}

/// Runs `runs` (one scene, material and N, several solvers) side by side: frame f of every
/// solver before frame f + 1 of any, so a shared machine's load falls on all of them alike.
/// Prints one JSON line per solver; from the second solver on, with its speed relative to the
/// first: the ratio of medians and the median of the per-frame ratios.
void MeasureSideBySide(const std::vector<Run>& runs) {
  std::vector<std::unique_ptr<Measurement>> measurements;
  for (const Run& run : runs) measurements.push_back(std::make_unique<Measurement>(run));
  for (int f = 0; f < runs.front().frames; ++f) {
    for (auto& m : measurements) m->AdvanceFrame();
  }
  const Measurement& first = *measurements.front();
  std::vector<std::pair<double, Eigen::MatrixXd>> references;  // (dt, CHOLMOD's positions)
  for (const auto& m : measurements) {
    json out = m->Report();
    if (m->run.own_error) AddOwnError(*m, references, out);
    if (m.get() != &first) {
      std::vector<double> ratios, cpu_ratios;
      for (std::size_t f = 0; f < m->ms.size(); ++f) {
        ratios.push_back(first.ms[f] / m->ms[f]);
        cpu_ratios.push_back(first.cpu_ms[f] / m->cpu_ms[f]);
      }
      const std::string versus = "speedup_vs_" + first.run.label;
      out[versus + "_median_ratio"] = Median(ratios);
      out[versus + "_ratio_of_medians"] = Median(first.ms) / Median(m->ms);
      out[versus + "_cpu_median_ratio"] = Median(cpu_ratios);
    }
    std::cout << out.dump() << std::endl;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cloth_bench: hang and drape scenes of docs/BENCHMARKS.md; one JSON line per run"};
  std::vector<std::string> scenes{"hang", "drape"};
  std::vector<std::string> materials{"stiff_cotton", "blender_cotton"};
  std::vector<int> sizes{33, 65, 129};
  std::vector<std::string> solvers{"pcg"};
  Run base;
  app.add_option("--scene", scenes, "Scenes")->check(CLI::IsMember({"hang", "drape"}))
      ->capture_default_str();
  app.add_option("--material", materials, "Materials")
      ->check(CLI::IsMember({"stiff_cotton", "blender_cotton"}))->capture_default_str();
  app.add_option("--n", sizes, "Lattice sizes N (N×N particles)")->check(CLI::Range(3, 1025))
      ->capture_default_str();
  app.add_option("--solver", solvers,
                 "Solvers, each NAME[,tol=T][,levels=L][,substeps=S][,threads=T] (NAME: pcg, "
                 "hierarchical, multigrid, multigrid_galerkin, multigrid_rediscretised, direct); "
                 "the settings override --tolerance, --levels, --dt and --threads for that "
                 "solver, e.g. --solver pcg,tol=1e-4 pcg,tol=1e-4,threads=2")
      ->capture_default_str();
  app.add_option("--dt", base.dt, "Time step [s]; rounded to 1/60 s divided by an integer")
      ->check(CLI::Range(1e-5, 1.0 / 60.0))->capture_default_str();
  app.add_option("--tolerance", base.tolerance, "PCG relative tolerance")
      ->check(CLI::Range(1e-14, 0.999))->capture_default_str();
  app.add_option("--max-iterations", base.max_iterations, "PCG iteration cap per step")
      ->check(CLI::Range(1, 1000000))->capture_default_str();
  app.add_option("--levels", base.levels, "Pyramid levels (hierarchical, multigrid); 0 = all")
      ->check(CLI::Range(0, 16))->capture_default_str();
  app.add_option("--strain-limit", base.strain_limit, "Strain limit after each step; 0 = off")
      ->check(CLI::Range(0.0, 10.0))->capture_default_str();
  app.add_option("--frames", base.frames, "Frames per run (60 per second)")
      ->check(CLI::Range(1, 100000))->capture_default_str();
  app.add_flag("--per-frame", base.per_frame,
               "Also print each frame's level-0 iterations (iterations_each_frame)");
  app.add_option("--threads", base.threads, "Threads of every solver's loops")
      ->check(CLI::Range(1, costume::sim::ThreadPool::kMaxThreads))->capture_default_str();
  app.add_flag("--own-error", base.own_error,
               "Also run each step size with CHOLMOD and print own_error_rms_mm: the RMS "
               "distance [mm] of every run from it at t = 1 s (the last frame if shorter)");
  CLI11_PARSE(app, argc, argv);
  try {
    for (const auto& scene : scenes) {
      for (const auto& material : materials) {
        for (int n : sizes) {
          std::vector<Run> runs;
          for (const auto& solver : solvers) {
            Run run = base;
            run.scene = scene;
            run.material = material;
            run.n = n;
            ApplySolverSpec(solver, run);
            runs.push_back(run);
          }
          MeasureSideBySide(runs);
        }
      }
    }
  } catch (const costume::sim::InputError& error) {
    std::fprintf(stderr, "error: %s\n", error.what());
    return 2;
  }
  return 0;
}
