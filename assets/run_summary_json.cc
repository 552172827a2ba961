#include "assets/run_summary_json.h"

#include <nlohmann/json.hpp>

namespace costume::assets {

namespace {

template <typename T>
nlohmann::json OrNull(const std::optional<T>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

}  // namespace

std::string RunSummaryJson(const sim::RunSummary& s) {
  nlohmann::ordered_json json = {
      {"particles", s.particles},
      {"frames", s.frames},
      {"ms_per_frame_median", s.ms_per_frame_median},
      {"ms_per_frame_p95", s.ms_per_frame_p95},
      {"solve_ms_median", s.solve_ms_median},
      {"strain_limit_ms_median", s.strain_limit_ms_median},
      {"collision_ms_median", s.collision_ms_median},
      {"self_collision_ms_median", s.self_collision_ms_median},
      {"max_strain", s.max_strain},
      {"max_strain_p99", s.max_strain_p99},
      {"mean_strain", s.mean_strain},
      {"penetration_max_mm", OrNull(s.penetration_max_mm)},
      {"penetration_p99_mm", OrNull(s.penetration_p99_mm)},
      {"crossing_edges_max", OrNull(s.crossing_edges_max)},
      {"nan", s.nan},
      {"steps_rolled_back", s.steps_rolled_back},
      {"steps_per_frame_mean", s.frames ? double(s.steps) / s.frames : 0.0},
      {"iterations_per_frame_mean", s.iterations_per_frame_mean},
  };
  if (!s.penetration_unmeasured.empty()) json["penetration_unmeasured"] = s.penetration_unmeasured;
  return json.dump();
}

}  // namespace costume::assets
