#pragma once
/// @file
/// How believable a running garment is, frame by frame, against yardsticks independent of
/// the engine's own colliders: the stretch of the structural springs, the depth of cloth
/// inside the true skinned mesh (MeshDistance, not the collider's proxy), and the cloth edges
/// through the cloth (CountCrossingEdges). `costume_sim --json` and `tools/garment_bench`
/// print its summary; docs/benchmarks.md lists the fields.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_core/collision/mesh_distance.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim {

/// What the measures of a whole run come to. Strains are length / rest − 1 of the
/// structural springs [-] (the face sides of a mesh, the lattice's axis springs: what a
/// fabric's warp and weft feel; shear and bending springs deform with the drape and are not
/// counted).
struct RunSummary {
  int particles = 0;
  int frames = 0;
  /// Wall time of a frame (Simulation::AdvanceFrame) [ms]: median and 95th percentile.
  double ms_per_frame_median = 0.0;
  double ms_per_frame_p95 = 0.0;
  /// Where a frame's time goes, medians over the frames [ms]: the implicit solve, the strain
  /// limit, the avatar's collision (following the body, contacts, corrections) and
  /// self-collision (FrameReport).
  double solve_ms_median = 0.0;
  double strain_limit_ms_median = 0.0;
  double collision_ms_median = 0.0;
  double self_collision_ms_median = 0.0;
  /// Largest strain of any structural spring in any frame [-].
  double max_strain = 0.0;
  /// 99th percentile over the frames of each frame's largest strain [-].
  double max_strain_p99 = 0.0;
  /// Mean over the frames of each frame's mean |strain| (stretch and compression) [-].
  double mean_strain = 0.0;
  /// Deepest particle inside the true skinned mesh in any frame, and the 99th percentile of
  /// the frames' deepest [mm]; empty when the scene has no avatar or its skin is not closed
  /// (inside is then undefined; `penetration_unmeasured` says why).
  std::optional<double> penetration_max_mm;
  std::optional<double> penetration_p99_mm;
  std::string penetration_unmeasured;
  /// Most cloth edges through the cloth in any frame; empty when not counted.
  std::optional<int> crossing_edges_max;
  /// Frames that ended with a non-finite position or velocity (the engine rolls such steps
  /// back, so this stays 0 unless that failed).
  int nan = 0;
  /// Steps undone for non-finite values, summed over the run (FrameReport).
  int steps_rolled_back = 0;
  /// Steps taken, summed over the run; and their mean per frame.
  int steps = 0;
  /// Solver iterations per frame: mean.
  double iterations_per_frame_mean = 0.0;
};

struct MetricsOptions {
  /// Count the edges through the cloth every frame (a tree over the triangles: about 1 ms
  /// for 3,000 particles).
  bool count_crossings = true;
  /// Depths are searched within this distance of the skin [m]: deeper points are missed.
  double penetration_search = 0.1;
};

/// Gathers the measures of a run, one frame at a time, outside the frame's timing.
class GarmentMetrics {
 public:
  /// Prepares the measures for `simulation` as built (its avatar's skin, its attached
  /// particles, which the body holds and which are not judged for penetration). Never throws
  /// for a skin that is not closed: its penetration is then reported as unmeasured.
  GarmentMetrics(const Simulation& simulation, MetricsOptions options = {});
  ~GarmentMetrics();

  /// Measures the frame `simulation` just advanced; `report` is what AdvanceFrame returned.
  void AddFrame(const Simulation& simulation, const FrameReport& report);

  RunSummary Summary() const;

  /// Per-frame values, in frame order (for plots and tests).
  const std::vector<double>& frame_max_strain() const { return frame_max_strain_; }
  const std::vector<double>& frame_mean_strain() const { return frame_mean_strain_; }
  const std::vector<double>& frame_penetration() const { return frame_penetration_; }
  const std::vector<int>& frame_crossings() const { return frame_crossings_; }

 private:
  MetricsOptions options_;
  int particles_ = 0;
  std::unique_ptr<MeshDistance> skin_;
  std::string unmeasured_;
  std::vector<char> attached_;
  std::vector<double> frame_ms_, frame_max_strain_, frame_mean_strain_, frame_penetration_;
  std::vector<double> solve_ms_, strain_limit_ms_, collision_ms_, self_collision_ms_;
  std::vector<int> frame_crossings_;
  int nan_ = 0, rolled_back_ = 0, steps_ = 0;
  long long iterations_ = 0;
};

}  // namespace costume::sim
