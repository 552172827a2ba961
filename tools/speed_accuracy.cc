/// @file
/// speed_accuracy: what each solver setting buys. Runs the hang and drape scenes of
/// docs/BENCHMARKS.md for every configuration (flat PCG over a range of tolerances, the
/// hierarchical step over its pyramid levels, multigrid PCG over the tolerances, CHOLMOD; each
/// at several substep counts) and measures time per frame against position error, both
/// against a reference run (CHOLMOD at 1/960 s) and against the converged (CHOLMOD) solve at
/// the configuration's own step, which isolates the linear solver's share of the error.
/// Writes a CSV, one SVG plot per scene and lattice size (error against time, Pareto front
/// marked), and prints which configuration is fastest within 1 mm, 5 mm and 2 cm.
/// Single-threaded. docs/benchmarks.md describes the columns and how to run it.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "assets/scene_file.h"
#include "sim_core/common/input_error.h"
#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/scene/simulation.h"
#include "sim_core/solver/spring_forces.h"

namespace {

using costume::sim::Points;
using costume::sim::SceneDescription;
using costume::sim::Simulation;
using costume::sim::SolverMethod;
using costume::sim::SolverMethodName;

/// Frames per second of every run [Hz] (docs/BENCHMARKS.md).
constexpr double kFrameRate = 60.0;
/// Substeps per frame of the reference run: CHOLMOD at 1/960 s.
constexpr int kReferenceSubsteps = 16;
/// RMS error thresholds of the summary table [m].
constexpr double kThresholds[] = {1e-3, 5e-3, 2e-2};
/// Marks "not measured / not applicable" in numbers; written as an empty CSV field.
constexpr double kMissing = std::numeric_limits<double>::quiet_NaN();

/// The command line.
struct Options {
  std::vector<std::string> scenes{"hang", "drape"};
  std::string material = "stiff_cotton";
  std::vector<int> sizes{33};
  std::vector<int> substeps{1, 2, 4, 8};
  std::vector<double> tolerances{1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8};
  std::vector<double> hierarchical_tolerances{1e-2};
  std::vector<std::string> solvers{"pcg", "hierarchical", "multigrid", "direct"};
  /// Pyramid levels the hierarchical solver is swept over; empty = 1 .. the most allowed.
  std::vector<int> hierarchical_levels;
  /// Keep the CHOLMOD runs (reference and same-step) in <out>/converged_cache and reuse them.
  bool use_cache = true;
  int max_iterations = 10000;
  double strain_limit = 0.1;
  std::string out = "out/speed_accuracy";
  int frames = 120;
};

/// One point of the sweep: a solver and its settings.
struct Config {
  SolverMethod method = SolverMethod::kPcg;
  /// Relative residual tolerance; kMissing for the direct solver.
  double tolerance = kMissing;
  /// Pyramid levels counting level 0 (hierarchical); 0 = as many as the lattice allows
  /// (multigrid); -1 = not applicable (pcg, direct).
  int levels = -1;
  int substeps = 1;
  /// The V-cycle's coarse operators (multigrid only).
  costume::sim::CoarseOperator coarse = costume::sim::CoarseOperator::kRediscretised;
};

/// RMS and max over particles of |x − x_ref| [m]; kMissing when not measured.
struct PositionError {
  double rms = kMissing;
  double max = kMissing;
};

/// What one simulation run measured.
struct RunResult {
  /// "ok" or "refused: <reason>".
  std::string status = "ok";
  double ms_per_frame_median = kMissing;
  double iterations_per_frame = kMissing;
  int unconverged_frames = 0;
  int rolled_back_steps = 0;
  /// Some frame ended with non-finite positions.
  bool nan = false;
  /// Structural strain after the last frame [-].
  costume::sim::StrainStats strain{kMissing, kMissing};
  /// Positions (n×3) [m] at each checkpoint frame.
  std::vector<Points> snapshots;

  bool is_ok() const { return status == "ok"; }
};

/// One line of the CSV: a configuration, its measurements and its errors per checkpoint.
struct Row {
  std::string scene;
  /// The cloth's material: --material, or the garment scene's own.
  std::string material;
  int n = 0;
  Config config;
  RunResult run;  // snapshots dropped once the errors are computed
  std::vector<PositionError> vs_reference;
  std::vector<PositionError> vs_same_step;

  /// RMS error against the reference at the last checkpoint [m], kMissing if unknown.
  double final_rms() const { return vs_reference.empty() ? kMissing : vs_reference.back().rms; }
  bool is_usable() const { return run.is_ok() && !run.nan && std::isfinite(final_rms()); }
};

/// printf into a std::string.
__attribute__((format(printf, 1, 2))) std::string Format(const char* format, ...) {
  char buffer[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buffer, sizeof(buffer), format, args);
  va_end(args);
  return buffer;
}

/// Compact scientific form: 1e-3, 2.5e-4, 0.5 stays "0.5"; empty for kMissing.
std::string FormatCompact(double value) {
  if (!std::isfinite(value)) return "";
  if (value == 0.0) return "0";
  const int exponent = static_cast<int>(std::floor(std::log10(std::abs(value)) + 1e-9));
  if (exponent >= -1 && exponent <= 3) return Format("%g", value);
  return Format("%.3ge%d", value / std::pow(10.0, exponent), exponent);
}

/// A length [m] in millimetres with three significant digits, e.g. "0.812 mm".
std::string FormatMm(double metres) {
  return std::isfinite(metres) ? Format("%.3g mm", metres * 1e3) : "n/a";
}

/// The number of pyramid levels (counting level 0) the hierarchical solver builds for an n×n
/// lattice with levels = 0: the pyramid's own count, so the sweep has no duplicate runs.
/// (Before the pyramid existed this was 1 + 2·floor(log2(n − 1)) − 2, halving down to 3×3.)
int MaxPyramidLevels(int n) {
  return std::clamp(costume::sim::QuincunxPyramid::MaxLevels(n, n), 1, 16);
}

/// The setting that distinguishes configurations of one solver: "tol=1e-3", "levels=3",
/// or "" (direct; multigrid always uses all levels).
std::string SettingText(const Config& config) {
  std::string text;
  if (std::isfinite(config.tolerance)) text = "tol=" + FormatCompact(config.tolerance);
  if (config.method == SolverMethod::kHierarchical) {
    text += (text.empty() ? "" : " ") + Format("levels=%d", config.levels);
  }
  return text;
}

/// The solver as named on the command line: "multigrid_galerkin" for the V-cycle on Galerkin
/// coarse operators, otherwise the method's name.
std::string SolverLabel(const Config& config) {
  if (config.method == SolverMethod::kMultigrid &&
      config.coarse == costume::sim::CoarseOperator::kGalerkin) {
    return "multigrid_galerkin";
  }
  return SolverMethodName(config.method);
}

/// "pcg tol=1e-3 substeps=2", for progress lines and tables.
std::string Describe(const Config& config) {
  std::string text = SolverLabel(config);
  const std::string setting = SettingText(config);
  if (!setting.empty()) text += " " + setting;
  return text + Format(" substeps=%d", config.substeps);
}

/// Frames at which positions are compared: a quarter, half and all of the run (frames 30,
/// 60, 120 = t 0.5, 1, 2 s by default).
std::vector<int> CheckpointFrames(int frames) {
  return {std::max(1, frames / 4), std::max(1, frames / 2), frames};
}

/// A checkpoint's time as written in column names and tables [s], e.g. "0.5", "2".
std::string CheckpointTime(int frame) { return Format("%.3g", frame / kFrameRate); }

/// The solver named on the command line ("pcg", "hierarchical", "multigrid",
/// "multigrid_galerkin", "direct").
SolverMethod ParseSolver(const std::string& name) {
  if (name == "hierarchical") return SolverMethod::kHierarchical;
  if (name == "multigrid" || name == "multigrid_galerkin") return SolverMethod::kMultigrid;
  if (name == "direct") return SolverMethod::kDirect;
  return SolverMethod::kPcg;
}

/// The hierarchical solver's level counts for an n×n lattice: --hierarchical-levels capped at
/// the most the lattice allows (each once), or all of 1 .. that most.
std::vector<int> HierarchicalLevels(const Options& options, int n) {
  std::vector<int> levels;
  for (int l = 1; l <= MaxPyramidLevels(n); ++l) {
    const bool wanted = options.hierarchical_levels.empty() ||
                        std::find(options.hierarchical_levels.begin(),
                                  options.hierarchical_levels.end(),
                                  l) != options.hierarchical_levels.end();
    if (wanted) levels.push_back(l);
  }
  return levels;
}

/// Every configuration to run for an n×n lattice, in the order of --solvers.
std::vector<Config> EnumerateConfigs(const Options& options, int n) {
  std::vector<Config> configs;
  for (const std::string& name : options.solvers) {
    const SolverMethod method = ParseSolver(name);
    const auto coarse = name == "multigrid_galerkin" ? costume::sim::CoarseOperator::kGalerkin
                                                     : costume::sim::CoarseOperator::kRediscretised;
    for (int substeps : options.substeps) {
      if (method == SolverMethod::kDirect) {
        configs.push_back({method, kMissing, -1, substeps});
      } else if (method == SolverMethod::kHierarchical) {
        for (double tolerance : options.hierarchical_tolerances) {
          for (int levels : HierarchicalLevels(options, n)) {
            configs.push_back({method, tolerance, levels, substeps});
          }
        }
      } else {
        const int levels = method == SolverMethod::kMultigrid ? 0 : -1;
        for (double tolerance : options.tolerances) {
          configs.push_back({method, tolerance, levels, substeps, coarse});
        }
      }
    }
  }
  return configs;
}

/// The material the scene's cloth is made of: --material for the lattice scenes, the garment
/// scene's own otherwise.
std::string MaterialOf(const Options& options, const std::string& scene_name) {
  const SceneDescription scene = costume::assets::LoadBuiltInScene(scene_name);
  const auto& garment = scene.garments.at(0);
  return garment.panel ? options.material : garment.material;
}

/// The built-in scene `scene_name` with an n×n lattice and `config`'s solver.
/// Throws costume::sim::InputError for an unknown scene.
SceneDescription MakeScene(const Options& options, const std::string& scene_name, int n,
                           const Config& config) {
  SceneDescription scene = costume::assets::LoadBuiltInScene(scene_name);
  auto& garment = scene.garments.at(0);
  if (garment.panel) {
    garment.panel->cols = garment.panel->rows = n;
    garment.material = options.material;
  } else {
    // The garment scene: a sewn skirt of its own material on the walking avatar; n is the
    // pattern's resolution (particles around the hem).
    garment.pattern_resolution = n;
  }
  scene.solver.method = config.method;
  // The direct solver ignores the tolerance; give it the tightest value the scene accepts.
  scene.solver.tolerance = std::isfinite(config.tolerance) ? config.tolerance : 1e-12;
  scene.solver.max_iterations = options.max_iterations;
  scene.solver.levels = std::max(0, config.levels);
  scene.solver.coarse_operator = config.coarse;
  scene.solver.substeps = config.substeps;
  scene.solver.strain_limit = options.strain_limit;
  scene.frame_rate = kFrameRate;
  scene.duration = options.frames / kFrameRate;
  return scene;
}

/// The median of `values`, kMissing when empty.
double Median(std::vector<double> values) {
  if (values.empty()) return kMissing;
  std::sort(values.begin(), values.end());
  const size_t mid = values.size() / 2;
  return values.size() % 2 == 1 ? values[mid] : 0.5 * (values[mid - 1] + values[mid]);
}

/// Runs one configuration for options.frames frames. A scene the engine refuses (InputError
/// from Simulation::Build, e.g. too stiff for its step) comes back with status "refused: ...".
RunResult RunConfig(const Options& options, const std::string& scene_name, int n,
                    const Config& config) {
  RunResult result;
  std::unique_ptr<Simulation> sim;
  try {
    sim = Simulation::Build(MakeScene(options, scene_name, n, config));
  } catch (const costume::sim::InputError& error) {
    result.status = std::string("refused: ") + error.what();
    return result;
  }
  const std::vector<int> checkpoints = CheckpointFrames(options.frames);
  std::vector<double> ms;
  long iterations = 0;
  for (int frame = 1; frame <= options.frames; ++frame) {
    const auto report = sim->AdvanceFrame();
    ms.push_back(report.wall_ms);
    iterations += report.iterations;
    result.unconverged_frames += report.converged ? 0 : 1;
    result.rolled_back_steps += report.rolled_back_steps;
    result.nan = result.nan || !sim->state().positions.allFinite();
    for (int checkpoint : checkpoints) {
      if (frame == checkpoint) result.snapshots.push_back(sim->state().positions);
    }
  }
  result.ms_per_frame_median = Median(ms);
  result.iterations_per_frame = static_cast<double>(iterations) / options.frames;
  result.strain = costume::sim::StructuralStrain(sim->model(), sim->state().positions);
  return result;
}

/// RMS and max over particles of |x − x_ref|; kMissing when either is missing or non-finite.
PositionError ComparePositions(const Points& x, const Points& reference) {
  if (x.rows() == 0 || x.rows() != reference.rows() || !x.allFinite() ||
      !reference.allFinite()) {
    return {};
  }
  const Eigen::VectorXd distance = (x - reference).rowwise().norm();
  return {std::sqrt(distance.squaredNorm() / static_cast<double>(distance.size())),
          distance.maxCoeff()};
}

/// Errors of `run` against `reference` at every checkpoint (kMissing where either lacks one).
std::vector<PositionError> CompareRuns(const RunResult& run, const RunResult& reference,
                                       size_t num_checkpoints) {
  std::vector<PositionError> errors(num_checkpoints);
  for (size_t i = 0; i < num_checkpoints; ++i) {
    if (i < run.snapshots.size() && i < reference.snapshots.size()) {
      errors[i] = ComparePositions(run.snapshots[i], reference.snapshots[i]);
    }
  }
  return errors;
}

// ---- CSV ---------------------------------------------------------------------------------

/// A CSV field: quoted (with doubled quotes) when it holds a comma, quote or newline.
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

/// A number for the CSV: 9 significant digits; empty for kMissing.
std::string CsvNumber(double value) {
  return std::isnan(value) ? "" : Format("%.9g", value);
}

/// The CSV's first line; error columns are named after the checkpoint times.
std::string CsvHeader(const std::vector<int>& checkpoints) {
  std::string header =
      "scene,material,n,solver,tolerance,levels,substeps,dt,ms_per_frame_median,"
      "iterations_per_frame,unconverged_frames,rolled_back_steps,nan,max_strain,mean_strain";
  for (const char* against : {"ref", "same_step"}) {
    for (int frame : checkpoints) {
      const std::string suffix = std::string(against) + "_" + CheckpointTime(frame);
      header += ",rms_" + suffix + ",max_" + suffix;
    }
  }
  return header + ",status";
}

/// One CSV line; measurements are empty for a refused configuration.
std::string CsvLine(const Row& row) {
  const Config& c = row.config;
  const RunResult& r = row.run;
  std::string line = CsvField(row.scene) + "," + CsvField(row.material) + "," +
                     std::to_string(row.n) + "," + SolverLabel(c) + "," +
                     CsvNumber(c.tolerance) + "," +
                     (c.levels >= 0 ? std::to_string(c.levels) : "") + "," +
                     std::to_string(c.substeps) + "," +
                     CsvNumber(1.0 / (kFrameRate * c.substeps)) + ",";
  if (r.is_ok()) {
    line += CsvNumber(r.ms_per_frame_median) + "," + CsvNumber(r.iterations_per_frame) + "," +
            std::to_string(r.unconverged_frames) + "," + std::to_string(r.rolled_back_steps) +
            "," + (r.nan ? "1" : "0") + "," + CsvNumber(r.strain.max) + "," +
            CsvNumber(r.strain.mean);
  } else {
    line += ",,,,,,";
  }
  for (const auto* errors : {&row.vs_reference, &row.vs_same_step}) {
    for (const PositionError& e : *errors) line += "," + CsvNumber(e.rms) + "," + CsvNumber(e.max);
  }
  return line + "," + CsvField(r.status);
}

// ---- SVG plot ----------------------------------------------------------------------------

/// A log10 axis from data range to pixels, widened to whole decades.
class LogAxis {
 public:
  /// Values in [min_value, max_value] (> 0) map into [pixel_from, pixel_to].
  LogAxis(double min_value, double max_value, double pixel_from, double pixel_to)
      : lo_(std::floor(std::log10(min_value))), hi_(std::ceil(std::log10(max_value))),
        pixel_from_(pixel_from), pixel_to_(pixel_to) {
    if (hi_ <= lo_) hi_ = lo_ + 1;
  }
  /// Pixel coordinate of `value` (clamped to the axis range).
  double Map(double value) const {
    const double t = (std::clamp(std::log10(value), lo_, hi_) - lo_) / (hi_ - lo_);
    return pixel_from_ + t * (pixel_to_ - pixel_from_);
  }
  /// Tick values: every decade, plus 2× and 5× when the axis spans at most two decades.
  std::vector<double> Ticks() const {
    std::vector<double> ticks;
    for (int e = static_cast<int>(lo_); e <= static_cast<int>(hi_); ++e) {
      for (double m : {1.0, 2.0, 5.0}) {
        const double value = m * std::pow(10.0, e);
        const bool is_shown = m == 1.0 || hi_ - lo_ <= 2;
        if (is_shown && std::log10(value) <= hi_ + 1e-9) ticks.push_back(value);
      }
    }
    return ticks;
  }
  bool Contains(double value) const {
    return std::log10(value) >= lo_ - 1e-9 && std::log10(value) <= hi_ + 1e-9;
  }
  double lowest() const { return std::pow(10.0, lo_); }

 private:
  double lo_, hi_, pixel_from_, pixel_to_;
};

/// Plot geometry [px].
constexpr double kPlotWidth = 1000, kPlotHeight = 640;
constexpr double kLeft = 90, kRight = 800, kTop = 60, kBottom = 570;

/// Marker colour of a solver in the plot.
const char* SolverColour(SolverMethod method) {
  switch (method) {
    case SolverMethod::kPcg: return "#1f77b4";
    case SolverMethod::kHierarchical: return "#ff7f0e";
    case SolverMethod::kMultigrid: return "#2ca02c";
    case SolverMethod::kDirect: return "#d62728";
  }
  return "#000000";
}

/// SVG path data of a solver's marker centred at (x, y): pcg circle, hierarchical square,
/// multigrid triangle, direct diamond (so that coinciding points of two solvers both show).
std::string MarkerPath(SolverMethod method, double x, double y) {
  switch (method) {
    case SolverMethod::kPcg:
      return Format("M%.1f,%.1f a4.5,4.5 0 1,0 9,0 a4.5,4.5 0 1,0 -9,0 Z", x - 4.5, y);
    case SolverMethod::kHierarchical: return Format("M%.1f,%.1f h8 v8 h-8 Z", x - 4, y - 4);
    case SolverMethod::kMultigrid: return Format("M%.1f,%.1f l5,9 h-10 Z", x, y - 5.5);
    case SolverMethod::kDirect:
      return Format("M%.1f,%.1f l5,5.5 l-5,5.5 l-5,-5.5 Z", x, y - 5.5);
  }
  return "";
}

/// Indices into `rows` of the Pareto front: usable configurations that no other is at least
/// as fast and strictly more accurate than, ordered from fastest to most accurate.
std::vector<size_t> ParetoFront(const std::vector<Row>& rows) {
  std::vector<size_t> order;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].is_usable()) order.push_back(i);
  }
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const double ta = rows[a].run.ms_per_frame_median, tb = rows[b].run.ms_per_frame_median;
    return ta != tb ? ta < tb : rows[a].final_rms() < rows[b].final_rms();
  });
  std::vector<size_t> front;
  double best_error = std::numeric_limits<double>::infinity();
  for (size_t i : order) {
    if (rows[i].final_rms() < best_error) {
      front.push_back(i);
      best_error = rows[i].final_rms();
    }
  }
  return front;
}

/// `text` with &, < and > escaped for SVG text.
std::string EscapeXml(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '&') out += "&amp;";
    else if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else out += c;
  }
  return out;
}

/// Frame, grid, tick labels and axis titles.
void WriteSvgAxes(std::ostream& svg, const LogAxis& x_axis, const LogAxis& y_axis,
                  const std::string& y_title) {
  svg << Format("<rect x='%g' y='%g' width='%g' height='%g' fill='none' stroke='#444'/>\n",
                kLeft, kTop, kRight - kLeft, kBottom - kTop);
  for (double tick : x_axis.Ticks()) {
    const double x = x_axis.Map(tick);
    svg << Format("<line x1='%.1f' y1='%g' x2='%.1f' y2='%g' stroke='#ddd'/>\n", x, kTop, x,
                  kBottom)
        << Format("<text x='%.1f' y='%g' text-anchor='middle'>%g</text>\n", x, kBottom + 18,
                  tick);
  }
  for (double tick : y_axis.Ticks()) {
    const double y = y_axis.Map(tick);
    svg << Format("<line x1='%g' y1='%.1f' x2='%g' y2='%.1f' stroke='#ddd'/>\n", kLeft, y,
                  kRight, y)
        << Format("<text x='%g' y='%.1f' text-anchor='end'>%s</text>\n", kLeft - 6, y + 4,
                  FormatCompact(tick).c_str());
  }
  svg << Format("<text x='%g' y='%g' text-anchor='middle'>ms per frame (median, log scale)"
                "</text>\n", (kLeft + kRight) / 2, kBottom + 42)
      << Format("<text transform='translate(%g,%g) rotate(-90)' text-anchor='middle'>%s"
                "</text>\n", kLeft - 62, (kTop + kBottom) / 2, EscapeXml(y_title).c_str());
}

/// Dashed horizontal lines at the table's thresholds that fall inside the y axis.
void WriteSvgThresholds(std::ostream& svg, const LogAxis& y_axis) {
  for (double threshold : kThresholds) {
    if (!y_axis.Contains(threshold)) continue;
    const double y = y_axis.Map(threshold);
    svg << Format("<line x1='%g' y1='%.1f' x2='%g' y2='%.1f' stroke='#999' "
                  "stroke-dasharray='6,4'/>\n", kLeft, y, kRight, y)
        << Format("<text x='%g' y='%.1f' fill='#777' font-size='11'>%s</text>\n", kLeft + 4,
                  y - 4, FormatMm(threshold).c_str());
  }
}

/// Solver colours and the Pareto front's line, right of the plot.
void WriteSvgLegend(std::ostream& svg) {
  double y = kTop + 10;
  svg << Format("<text x='%g' y='%g' font-weight='bold'>solver</text>\n", kRight + 20, y);
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kHierarchical,
                              SolverMethod::kMultigrid, SolverMethod::kDirect}) {
    y += 20;
    svg << Format("<path d='%s' fill='%s'/>\n", MarkerPath(method, kRight + 26, y - 4).c_str(),
                  SolverColour(method))
        << Format("<text x='%g' y='%g'>%s</text>\n", kRight + 38, y, SolverMethodName(method));
  }
  y += 24;
  svg << Format("<line x1='%g' y1='%g' x2='%g' y2='%g' stroke='black' stroke-width='1.5'/>\n",
                kRight + 18, y - 4, kRight + 34, y - 4)
      << Format("<text x='%g' y='%g'>Pareto front</text>\n", kRight + 38, y);
}

/// A rectangle on the plot [px], for keeping labels apart.
struct Box {
  double left, top, right, bottom;
  bool Overlaps(const Box& other) const {
    return left < other.right && other.left < right && top < other.bottom &&
           other.top < bottom;
  }
  bool IsInsidePlot() const {
    return left >= kLeft && right <= kRight && top >= kTop && bottom <= kBottom;
  }
};

/// Where a label of `length` characters (font size 10) goes near the point (x, y): right of
/// it, else left, nearest first, then further up or down, in the first spot that overlaps
/// nothing in `taken` and stays inside the plot. Returns the box, which it adds to `taken`.
Box PlaceLabel(double x, double y, size_t length, std::vector<Box>& taken) {
  const double width = 5.6 * static_cast<double>(length), height = 12.0;
  std::vector<Box> candidates;
  for (int k = 0; k < 24; ++k) {
    const double baseline = y + (k % 2 == 0 ? -6.0 - 14.0 * (k / 2) : 14.0 + 14.0 * (k / 2));
    candidates.push_back({x + 8, baseline - height + 2, x + 8 + width, baseline + 2});
    candidates.push_back({x - 8 - width, baseline - height + 2, x - 8, baseline + 2});
  }
  Box chosen = candidates.front();
  for (const Box& box : candidates) {
    const bool is_free = std::none_of(taken.begin(), taken.end(),
                                      [&](const Box& other) { return box.Overlaps(other); });
    if (is_free && box.IsInsidePlot()) {
      chosen = box;
      break;
    }
  }
  taken.push_back(chosen);
  return chosen;
}

/// Markers for every usable configuration (hover text: the configuration), then the Pareto
/// front: a line through its points, each circled and labelled (with a leader line when the
/// label had to move away from its point).
void WriteSvgPoints(std::ostream& svg, const std::vector<Row>& rows, const LogAxis& x_axis,
                    const LogAxis& y_axis) {
  auto point = [&](const Row& row) {
    return std::pair{x_axis.Map(row.run.ms_per_frame_median),
                     y_axis.Map(std::max(row.final_rms(), y_axis.lowest()))};
  };
  for (const Row& row : rows) {
    if (!row.is_usable()) continue;
    const auto [x, y] = point(row);
    svg << Format("<path d='%s' fill='%s' fill-opacity='0.75'><title>%s: %.3g ms, %s</title>"
                  "</path>\n", MarkerPath(row.config.method, x, y).c_str(),
                  SolverColour(row.config.method), Describe(row.config).c_str(),
                  row.run.ms_per_frame_median, FormatMm(row.final_rms()).c_str());
  }
  const std::vector<size_t> front = ParetoFront(rows);
  std::string polyline;
  std::vector<Box> taken;  // the front's markers, then each label placed
  for (size_t i : front) {
    const auto [x, y] = point(rows[i]);
    polyline += Format("%.1f,%.1f ", x, y);
    taken.push_back({x - 7, y - 7, x + 7, y + 7});
  }
  svg << "<polyline points='" << polyline << "' fill='none' stroke='black' "
      << "stroke-width='1.5'/>\n";
  for (size_t i : front) {
    const auto [x, y] = point(rows[i]);
    const std::string label = Describe(rows[i].config);
    const Box box = PlaceLabel(x, y, label.size(), taken);
    const bool is_right = box.left > x;
    svg << Format("<circle cx='%.1f' cy='%.1f' r='7' fill='none' stroke='black'/>\n", x, y)
        << Format("<text x='%.1f' y='%.1f' font-size='10' text-anchor='%s' stroke='white' "
                  "stroke-width='3' paint-order='stroke'>%s</text>\n",
                  is_right ? box.left : box.right, box.bottom - 2, is_right ? "start" : "end",
                  label.c_str());
    if (box.top > y + 4 || box.bottom < y - 4) {
      svg << Format("<line x1='%.1f' y1='%.1f' x2='%.1f' y2='%.1f' stroke='#888' "
                    "stroke-width='0.7'/>\n", x, y, is_right ? box.left - 1 : box.right + 1,
                    0.5 * (box.top + box.bottom));
    }
  }
}

/// Writes the plot of one scene and lattice size: ms per frame against RMS error vs the
/// reference at the last checkpoint, both log scale. Returns false when nothing is plottable.
bool WriteSvg(const std::string& path, const std::vector<Row>& rows, const std::string& time) {
  double t_min = INFINITY, t_max = 0, e_min = INFINITY, e_max = 0;
  int num_hidden = 0;
  for (const Row& row : rows) {
    if (!row.is_usable()) {
      ++num_hidden;
      continue;
    }
    t_min = std::min(t_min, row.run.ms_per_frame_median);
    t_max = std::max(t_max, row.run.ms_per_frame_median);
    if (row.final_rms() > 0) e_min = std::min(e_min, row.final_rms());
    e_max = std::max(e_max, row.final_rms());
  }
  if (!(t_max > 0) || !(e_max > 0)) return false;
  const LogAxis x_axis(t_min, t_max, kLeft, kRight);
  const LogAxis y_axis(e_min, e_max, kBottom, kTop);
  std::ofstream svg(path);
  svg << Format("<svg xmlns='http://www.w3.org/2000/svg' width='%g' height='%g' "
                "font-family='sans-serif' font-size='12'>\n", kPlotWidth, kPlotHeight)
      << "<rect width='100%' height='100%' fill='white'/>\n"
      << Format("<text x='%g' y='28' text-anchor='middle' font-size='16'>%s, %s, n = %d: "
                "speed against accuracy at t = %s s</text>\n", (kLeft + kRight) / 2,
                EscapeXml(rows.front().scene).c_str(), EscapeXml(rows.front().material).c_str(),
                rows.front().n, time.c_str());
  if (num_hidden > 0) {
    svg << Format("<text x='%g' y='46' text-anchor='middle' fill='#777' font-size='11'>%d "
                  "refused or non-finite configurations not shown; errors of 0 drawn on the "
                  "bottom edge</text>\n", (kLeft + kRight) / 2, num_hidden);
  }
  WriteSvgAxes(svg, x_axis, y_axis, "RMS position error vs reference at t = " + time + " s [m]");
  WriteSvgThresholds(svg, y_axis);
  WriteSvgPoints(svg, rows, x_axis, y_axis);
  WriteSvgLegend(svg);
  svg << "</svg>\n";
  return static_cast<bool>(svg);
}

// ---- Summary table -----------------------------------------------------------------------

/// The fastest usable row whose final RMS error is within `threshold`, or nullptr.
const Row* FastestWithin(const std::vector<Row>& rows, double threshold) {
  const Row* best = nullptr;
  for (const Row& row : rows) {
    if (!row.is_usable() || row.final_rms() > threshold) continue;
    if (best == nullptr || row.run.ms_per_frame_median < best->run.ms_per_frame_median) {
      best = &row;
    }
  }
  return best;
}

/// The usable row with the smallest final RMS error (the fastest among equals), or nullptr.
const Row* MostAccurate(const std::vector<Row>& rows) {
  const Row* best = nullptr;
  for (const Row& row : rows) {
    if (!row.is_usable()) continue;
    if (best == nullptr || row.final_rms() < best->final_rms() ||
        (row.final_rms() == best->final_rms() &&
         row.run.ms_per_frame_median < best->run.ms_per_frame_median)) {
      best = &row;
    }
  }
  return best;
}

/// For each threshold, the fastest configuration within it, or "none" and the most accurate.
void PrintThresholdTable(const std::vector<Row>& rows, const std::string& time) {
  std::printf("  fastest configuration within an RMS error vs reference at t = %s s of\n",
              time.c_str());
  std::printf("    %-8s %-44s %10s %12s\n", "error", "configuration", "ms/frame", "RMS error");
  for (double threshold : kThresholds) {
    const Row* best = FastestWithin(rows, threshold);
    if (best == nullptr) {
      const Row* closest = MostAccurate(rows);
      const std::string note = closest == nullptr ? "" : Format(
          " (most accurate: %s, %.3g ms/frame, %s)", Describe(closest->config).c_str(),
          closest->run.ms_per_frame_median, FormatMm(closest->final_rms()).c_str());
      std::printf("    %-8s none%s\n", FormatMm(threshold).c_str(), note.c_str());
      continue;
    }
    std::printf("    %-8s %-44s %10.3g %12s\n", FormatMm(threshold).c_str(),
                Describe(best->config).c_str(), best->run.ms_per_frame_median,
                FormatMm(best->final_rms()).c_str());
  }
}

/// Slack of "equal error": within 1 % of the baseline's error counts as equal, so that the
/// baseline itself and settings whose solutions agree with it to round-off qualify.
constexpr double kEqualErrorSlack = 1.01;

/// The RMS errors of `errors`, space-separated: "3.67 mm 6.47 mm 17.9 mm".
std::string JoinMm(const std::vector<PositionError>& errors) {
  std::string text;
  for (const PositionError& e : errors) {
    if (!text.empty()) text.append(" ");
    text.append(FormatMm(e.rms));
  }
  return text;
}

/// Which error "equal error" compares: against the reference, or the solver's own share
/// (against the converged solve at the row's own step).
using ErrorKind = std::vector<PositionError> Row::*;

/// True when `row`'s RMS error of `kind` is at most `baseline`'s (with the slack) at every
/// checkpoint: no worse at t = 0.5, 1 and 2 s, not just at the end.
bool IsAtMostAsWrong(const Row& row, const Row& baseline, ErrorKind kind) {
  if (!row.is_usable()) return false;
  const std::vector<PositionError>& limits = baseline.*kind;
  const std::vector<PositionError>& errors = row.*kind;
  for (size_t c = 0; c < limits.size(); ++c) {
    const double limit = limits[c].rms * kEqualErrorSlack;
    if (c >= errors.size() || !(errors[c].rms <= limit)) return false;
  }
  return true;
}

/// One line per solver: its fastest row at most as wrong as `baseline` in `kind`.
void PrintFastestAtEqualError(const std::vector<Row>& rows, const Row& baseline, ErrorKind kind) {
  std::vector<std::string> labels;
  for (const Row& row : rows) {
    if (std::find(labels.begin(), labels.end(), SolverLabel(row.config)) == labels.end()) {
      labels.push_back(SolverLabel(row.config));
    }
  }
  for (const std::string& label : labels) {
    const Row* best = nullptr;
    for (const Row& row : rows) {
      if (SolverLabel(row.config) != label || !IsAtMostAsWrong(row, baseline, kind)) continue;
      if (best == nullptr || row.run.ms_per_frame_median < best->run.ms_per_frame_median) {
        best = &row;
      }
    }
    if (best == nullptr) {
      std::printf("    %-20s none\n", label.c_str());
      continue;
    }
    std::printf("    %-20s %-40s %9.3g ms/frame  %5.2fx  (%s)\n", label.c_str(),
                Describe(best->config).c_str(), best->run.ms_per_frame_median,
                baseline.run.ms_per_frame_median / best->run.ms_per_frame_median,
                JoinMm(best->*kind).c_str());
  }
}

/// The yardstick: at the error of flat PCG at tolerance 1e-4 (fewest substeps swept),
/// the fastest configuration of each solver that is no less accurate at any checkpoint, and
/// its speed-up; once against the reference (where the time step's own error dominates and
/// loose tolerances qualify) and once for the solver's own share (against the converged
/// solve at the same step, where they do not). Timings are sequential here; tools/cloth_bench
/// runs the chosen settings side by side for ratios that do not drift with the load.
void PrintEqualErrorTable(const std::vector<Row>& rows) {
  const Row* baseline = nullptr;
  for (const Row& row : rows) {
    const bool is_candidate = row.config.method == SolverMethod::kPcg &&
                              row.config.tolerance == 1e-4 && row.is_usable();
    if (is_candidate && (baseline == nullptr || row.config.substeps < baseline->config.substeps)) {
      baseline = &row;
    }
  }
  if (baseline == nullptr) {
    std::printf("  equal error: no pcg tol=1e-4 run in the sweep (add 1e-4 to --tolerances)\n");
    return;
  }
  using Yardstick = std::pair<ErrorKind, const char*>;
  for (const auto& [kind, against] :
       {Yardstick{&Row::vs_reference, "vs reference"},
        Yardstick{&Row::vs_same_step, "own share (vs CHOLMOD, same step)"}}) {
    std::printf("  at the RMS error %s of %s (at the checkpoints: %s; %.3g ms/frame),\n"
                "  the fastest configuration of each solver no less accurate at every "
                "checkpoint (1 %% slack)\n",
                against, Describe(baseline->config).c_str(), JoinMm(baseline->*kind).c_str(),
                baseline->run.ms_per_frame_median);
    PrintFastestAtEqualError(rows, *baseline, kind);
  }
}

/// Matrix of the solver's own share of the error: one line per solver setting, one column
/// per substep count; the first line is the step's own error (CHOLMOD vs reference).
void PrintSolverShareTable(const Options& options, const std::vector<Row>& rows,
                           const std::map<int, double>& step_error, const std::string& time) {
  std::printf("  solver's own share: RMS error at t = %s s vs the converged (CHOLMOD) solve at "
              "the same step\n    %-28s", time.c_str(), "configuration");
  for (int substeps : options.substeps) {
    std::printf(" %12s", Format("substeps=%d", substeps).c_str());
  }
  std::printf("\n    %-28s", "(step error: CHOLMOD vs ref)");
  for (int substeps : options.substeps) {
    std::printf(" %12s", FormatMm(step_error.at(substeps)).c_str());
  }
  std::printf("\n");
  std::vector<std::string> settings;  // solver + setting, in sweep order, each once
  std::map<std::pair<std::string, int>, const Row*> cells;
  for (const Row& row : rows) {
    const std::string name = SolverLabel(row.config) + " " + SettingText(row.config);
    if (std::find(settings.begin(), settings.end(), name) == settings.end()) {
      settings.push_back(name);
    }
    cells[{name, row.config.substeps}] = &row;
  }
  for (const std::string& name : settings) {
    std::printf("    %-28s", name.c_str());
    for (int substeps : options.substeps) {
      const auto cell = cells.find({name, substeps});
      const Row* row = cell == cells.end() ? nullptr : cell->second;
      const std::string text = row == nullptr       ? "-"
                               : !row->run.is_ok()  ? "refused"
                               : row->run.nan       ? "nan"
                                                    : FormatMm(row->vs_same_step.back().rms);
      std::printf(" %12s", text.c_str());
    }
    std::printf("\n");
  }
}

// ---- The sweep ---------------------------------------------------------------------------

// ---- Cached CHOLMOD runs ------------------------------------------------------------------
// The reference costs minutes at N = 129 (16 CHOLMOD steps per frame); a sweep repeated with
// other solvers reuses it from disk. The file name holds every option the run depends on; a
// change to the engine itself is not seen, hence --no-cache.

constexpr char kCacheMagic[] = "speed_accuracy converged run v1";

/// <out>/converged_cache/<scene>_<material>_n<n>_f<frames>_s<substeps>_sl<strain limit>.bin
std::filesystem::path CachePath(const Options& options, const std::string& scene, int n,
                                int substeps) {
  return std::filesystem::path(options.out) / "converged_cache" /
         Format("%s_%s_n%d_f%d_s%d_sl%g.bin", scene.c_str(), MaterialOf(options, scene).c_str(), n,
                options.frames, substeps, options.strain_limit);
}

template <typename T>
void WriteValue(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
bool ReadValue(std::istream& in, T& value) {
  return static_cast<bool>(in.read(reinterpret_cast<char*>(&value), sizeof(T)));
}

/// Writes `run` (an "ok" run) to `path`; a failure only costs the reuse.
void SaveRun(const std::filesystem::path& path, const RunResult& run) {
  std::error_code error;
  std::filesystem::create_directories(path.parent_path(), error);
  const std::filesystem::path partial = path.string() + ".partial";
  {
    std::ofstream out(partial, std::ios::binary);
    out << kCacheMagic << '\n';
    WriteValue(out, run.ms_per_frame_median);
    WriteValue(out, run.iterations_per_frame);
    WriteValue(out, run.unconverged_frames);
    WriteValue(out, run.rolled_back_steps);
    WriteValue(out, run.nan);
    WriteValue(out, run.strain.max);
    WriteValue(out, run.strain.mean);
    WriteValue(out, static_cast<std::int64_t>(run.snapshots.size()));
    for (const Points& x : run.snapshots) {
      WriteValue(out, static_cast<std::int64_t>(x.rows()));
      out.write(reinterpret_cast<const char*>(x.data()),
                static_cast<std::streamsize>(sizeof(double) * x.size()));
    }
    if (!out) return;
  }
  std::filesystem::rename(partial, path, error);  // whole files only
}

/// The run stored at `path` if it is there and whole. (Comparisons check the particle
/// counts against the runs they meet.)
std::optional<RunResult> LoadRun(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string magic;
  if (!in || !std::getline(in, magic) || magic != kCacheMagic) return std::nullopt;
  RunResult run;
  std::int64_t num_snapshots = 0;
  bool ok = ReadValue(in, run.ms_per_frame_median) && ReadValue(in, run.iterations_per_frame) &&
            ReadValue(in, run.unconverged_frames) && ReadValue(in, run.rolled_back_steps) &&
            ReadValue(in, run.nan) && ReadValue(in, run.strain.max) &&
            ReadValue(in, run.strain.mean) && ReadValue(in, num_snapshots);
  if (!ok || num_snapshots < 0 || num_snapshots > 64) return std::nullopt;
  for (std::int64_t i = 0; i < num_snapshots; ++i) {
    std::int64_t rows = 0;
    if (!ReadValue(in, rows) || rows <= 0 || rows > (1 << 26)) return std::nullopt;
    Points x(rows, 3);
    if (!in.read(reinterpret_cast<char*>(x.data()),
                 static_cast<std::streamsize>(sizeof(double) * x.size()))) {
      return std::nullopt;
    }
    run.snapshots.push_back(std::move(x));
  }
  return run;
}

/// Runs and caches the CHOLMOD runs of one scene and lattice size, keyed by substeps.
class ConvergedRuns {
 public:
  ConvergedRuns(const Options& options, std::string scene, int n)
      : options_(options), scene_(std::move(scene)), n_(n) {}

  /// The CHOLMOD run at `substeps` per frame: from memory, from the disk cache, or run.
  const RunResult& Get(int substeps) {
    auto found = runs_.find(substeps);
    if (found != runs_.end()) return found->second;
    const Config config{SolverMethod::kDirect, kMissing, -1, substeps};
    std::fprintf(stderr, "[converged] %s n=%d %s ... ", scene_.c_str(), n_,
                 Describe(config).c_str());
    const std::filesystem::path path = CachePath(options_, scene_, n_, substeps);
    if (options_.use_cache) {
      if (std::optional<RunResult> cached = LoadRun(path)) {
        std::fprintf(stderr, "reused %s\n", path.c_str());
        return runs_.emplace(substeps, std::move(*cached)).first->second;
      }
    }
    RunResult run = RunConfig(options_, scene_, n_, config);
    const std::string outcome =
        run.is_ok() ? Format("%.3g ms/frame", run.ms_per_frame_median) : run.status;
    std::fprintf(stderr, "%s\n", outcome.c_str());
    if (options_.use_cache && run.is_ok()) SaveRun(path, run);
    return runs_.emplace(substeps, std::move(run)).first->second;
  }

 private:
  const Options& options_;
  std::string scene_;
  int n_;
  std::map<int, RunResult> runs_;
};

/// Progress counter shared by the whole sweep.
struct Progress {
  int done = 0;
  int total = 0;
};

/// The outcome of one scene and lattice size.
struct SceneResult {
  /// One per configuration, positions dropped.
  std::vector<Row> rows;
  /// The step's own error per substep count: RMS of CHOLMOD at that step vs the reference at
  /// the last checkpoint [m].
  std::map<int, double> step_error;
};

/// Runs every configuration of one scene and lattice size, appending each row to `csv` as
/// it completes.
SceneResult SweepScene(const Options& options, const std::string& scene, int n,
                       std::ostream& csv, Progress& progress) {
  ConvergedRuns converged(options, scene, n);
  const RunResult& reference = converged.Get(kReferenceSubsteps);
  const size_t num_checkpoints = CheckpointFrames(options.frames).size();
  const std::string time = CheckpointTime(options.frames);
  SceneResult result;
  for (const Config& config : EnumerateConfigs(options, n)) {
    const RunResult& same_step = converged.Get(config.substeps);  // before the progress line
    std::fprintf(stderr, "[%d/%d] %s n=%d %s ... ", ++progress.done, progress.total,
                 scene.c_str(), n, Describe(config).c_str());
    Row row{scene, MaterialOf(options, scene), n, config, {}, {}, {}};
    // A CHOLMOD configuration is its own converged solve: run it once.
    const auto start = std::chrono::steady_clock::now();
    row.run = config.method == SolverMethod::kDirect ? same_step
                                                     : RunConfig(options, scene, n, config);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    row.vs_reference = CompareRuns(row.run, reference, num_checkpoints);
    row.vs_same_step = CompareRuns(row.run, same_step, num_checkpoints);
    row.run.snapshots.clear();
    if (row.run.is_ok()) {
      const std::string took = config.method == SolverMethod::kDirect
                                   ? "(the converged run)" : Format("(%.1f s)", seconds);
      std::fprintf(stderr, "%.3g ms/frame, rms@%ss %s%s %s\n", row.run.ms_per_frame_median,
                   time.c_str(), FormatMm(row.final_rms()).c_str(),
                   row.run.nan ? " (NaN)" : "", took.c_str());
    } else {
      std::fprintf(stderr, "%s\n", row.run.status.c_str());
    }
    csv << CsvLine(row) << std::endl;
    result.rows.push_back(std::move(row));
  }
  for (int substeps : options.substeps) {
    result.step_error[substeps] =
        CompareRuns(converged.Get(substeps), reference, num_checkpoints).back().rms;
  }
  return result;
}

/// Declares the command-line options, with their defaults shown in --help.
void AddOptions(CLI::App& app, Options& options) {
  app.add_option("--scene", options.scenes,
                 "Scenes to run (garment: the built-in skirt on the walking avatar, mesh "
                 "collision; its own material, n = the pattern's resolution)")
      ->check(CLI::IsMember({"hang", "drape", "garment"}))->capture_default_str();
  app.add_option("--material", options.material,
                 "Built-in material of the cloth (hang and drape)")
      ->check(CLI::IsMember({"stiff_cotton", "blender_cotton"}))->capture_default_str();
  app.add_option("--n", options.sizes, "Lattice sizes N (N×N particles); several allowed")
      ->check(CLI::Range(3, 1025))->capture_default_str();
  app.add_option("--substeps", options.substeps, "Implicit steps per 1/60 s frame")
      ->check(CLI::Range(1, 256))->capture_default_str();
  app.add_option("--tolerances", options.tolerances,
                 "Relative residual tolerances swept by pcg and multigrid")
      ->check(CLI::Range(1e-14, 0.999))->capture_default_str();
  app.add_option("--hierarchical-tolerances", options.hierarchical_tolerances,
                 "Tolerances of the hierarchical solver, each swept over 1..max pyramid levels")
      ->check(CLI::Range(1e-14, 0.999))->capture_default_str();
  app.add_option("--solvers", options.solvers, "Solvers to sweep")
      ->check(CLI::IsMember({"pcg", "hierarchical", "multigrid", "multigrid_galerkin", "direct"}))
      ->capture_default_str();
  app.add_option("--hierarchical-levels", options.hierarchical_levels,
                 "Pyramid levels the hierarchical solver is swept over (counting level 0); "
                 "default: 1 .. the most the lattice allows")
      ->check(CLI::Range(1, 16));
  app.add_flag("!--no-cache", options.use_cache,
               "Recompute the CHOLMOD runs instead of reusing <out>/converged_cache");
  app.add_option("--max-iterations", options.max_iterations, "Iteration cap per step")
      ->check(CLI::Range(1, 10000000))->capture_default_str();
  app.add_option("--strain-limit", options.strain_limit, "Strain limit after each step; 0 = off")
      ->check(CLI::Range(0.0, 10.0))->capture_default_str();
  app.add_option("--out", options.out,
                 "Folder for speed_accuracy.csv and speed_accuracy_<scene>_<n>.svg")
      ->capture_default_str();
  app.add_option("--frames", options.frames,
                 "Frames per run (60 per second); errors are compared after a quarter, half "
                 "and all of them (t = 0.5, 1, 2 s by default)")
      ->check(CLI::Range(4, 100000))->capture_default_str();
}

/// Number of configurations over all scenes and sizes (reference runs not counted).
int TotalConfigs(const Options& options) {
  int total = 0;
  for (int n : options.sizes) total += static_cast<int>(EnumerateConfigs(options, n).size());
  return total * static_cast<int>(options.scenes.size());
}

}  // namespace

/// Opens the CSV for this sweep's rows: a new file gets `header`; an earlier sweep's file with
/// the same columns is appended to (a second sweep into the same folder loses nothing); one
/// with other columns (another --frames) is refused with a message. False on refusal.
bool OpenCsv(const std::string& path, const std::string& header, std::ofstream& csv) {
  std::string existing;
  if (std::ifstream in(path); in && std::getline(in, existing) && existing != header) {
    std::fprintf(stderr,
                 "error: %s holds an earlier sweep with other columns (another --frames); "
                 "pick another --out or move the file\n", path.c_str());
    return false;
  }
  const bool is_new = existing.empty();
  csv.open(path, std::ios::app);
  if (!csv) {
    std::fprintf(stderr, "error: cannot write %s\n", path.c_str());
    return false;
  }
  if (is_new) csv << header << std::endl;
  return true;
}

int main(int argc, char** argv) {
  CLI::App app{"speed_accuracy: time per frame against position error for every solver "
               "configuration on the hang and drape scenes (docs/benchmarks.md)"};
  Options options;
  AddOptions(app, options);
  CLI11_PARSE(app, argc, argv);
  std::filesystem::create_directories(options.out);
  const std::string csv_path = options.out + "/speed_accuracy.csv";
  std::ofstream csv;
  if (!OpenCsv(csv_path, CsvHeader(CheckpointFrames(options.frames)), csv)) return 2;
  const auto start = std::chrono::steady_clock::now();
  Progress progress{0, TotalConfigs(options)};
  const std::string time = CheckpointTime(options.frames);
  for (const std::string& scene : options.scenes) {
    for (int n : options.sizes) {
      const SceneResult result = SweepScene(options, scene, n, csv, progress);
      const std::vector<Row>& rows = result.rows;
      const std::string svg_path = options.out + "/speed_accuracy_" + scene + "_" +
                                   std::to_string(n) + ".svg";
      const bool plotted = WriteSvg(svg_path, rows, time);
      std::printf("%s, %s, n = %d%s\n", scene.c_str(), MaterialOf(options, scene).c_str(), n,
                  plotted ? (" (plot: " + svg_path + ")").c_str() : " (nothing to plot)");
      PrintThresholdTable(rows, time);
      PrintEqualErrorTable(rows);
      PrintSolverShareTable(options, rows, result.step_error, time);
      std::printf("\n");
      std::fflush(stdout);
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::fprintf(stderr, "%d configurations in %.1f s; CSV: %s\n", progress.total, seconds,
               csv_path.c_str());
  return 0;
}
