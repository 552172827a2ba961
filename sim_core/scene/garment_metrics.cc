#include "sim_core/scene/garment_metrics.h"

#include <algorithm>
#include <cmath>

#include "sim_core/collision/self_collision.h"
#include "sim_core/common/input_error.h"
#include "sim_core/common/percentile.h"
#include "sim_core/solver/spring_forces.h"

namespace costume::sim {

namespace {

template <typename T>
T PercentileOf(std::vector<T> values, double q) {
  if (values.empty()) return T{};
  std::sort(values.begin(), values.end());
  return NearestRankPercentile(values.data(), static_cast<std::int64_t>(values.size()), q);
}

double Mean(const std::vector<double>& values) {
  if (values.empty()) return 0.0;
  double sum = 0.0;
  for (double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

}  // namespace

GarmentMetrics::GarmentMetrics(const Simulation& simulation, MetricsOptions options)
    : options_(options), particles_(simulation.model().num_particles()) {
  attached_.assign(particles_, 0);
  for (const BodyAttachment& a : simulation.attachments()) attached_[a.particle] = 1;
  const AvatarMotion* avatar = simulation.avatar();
  if (!avatar) {
    unmeasured_ = "the scene has no avatar";
    return;
  }
  try {
    skin_ = std::make_unique<MeshDistance>(avatar->avatar().name(), avatar->vertices(),
                                           avatar->avatar().triangles());
  } catch (const InputError& error) {
    unmeasured_ = std::string("the skin is not a closed surface: ") + error.what();
  }
}

GarmentMetrics::~GarmentMetrics() = default;

void GarmentMetrics::AddFrame(const Simulation& simulation, const FrameReport& report) {
  const Points& x = simulation.state().positions;
  frame_ms_.push_back(report.wall_ms);
  solve_ms_.push_back(report.solve_ms);
  strain_limit_ms_.push_back(report.strain_limit_ms);
  collision_ms_.push_back(report.collision_ms + report.collision_update_ms);
  self_collision_ms_.push_back(report.self_collision_ms);
  rolled_back_ += report.rolled_back_steps;
  steps_ += report.steps;
  iterations_ += report.iterations;
  if (!x.allFinite() || !simulation.state().velocities.allFinite()) {
    ++nan_;
    return;  // nothing below means anything for this frame
  }
  const StrainStats strain = StructuralStrain(simulation.model(), x);
  frame_max_strain_.push_back(strain.max);
  frame_mean_strain_.push_back(strain.mean);
  if (skin_) {
    skin_->Update(simulation.avatar()->vertices());
    double deepest = 0.0;
    for (Eigen::Index p = 0; p < x.rows(); ++p) {
      if (attached_[p]) continue;  // held where the body puts it, inside or not
      deepest = std::max(deepest,
                         skin_->PenetrationDepth(x.row(p).transpose(), options_.penetration_search));
    }
    frame_penetration_.push_back(deepest);
  }
  if (options_.count_crossings) {
    frame_crossings_.push_back(CountCrossingEdges(simulation.model(), x));
  }
}

RunSummary GarmentMetrics::Summary() const {
  RunSummary s;
  s.particles = particles_;
  s.frames = static_cast<int>(frame_ms_.size());
  s.ms_per_frame_median = PercentileOf(frame_ms_, 0.5);
  s.ms_per_frame_p95 = PercentileOf(frame_ms_, 0.95);
  s.solve_ms_median = PercentileOf(solve_ms_, 0.5);
  s.strain_limit_ms_median = PercentileOf(strain_limit_ms_, 0.5);
  s.collision_ms_median = PercentileOf(collision_ms_, 0.5);
  s.self_collision_ms_median = PercentileOf(self_collision_ms_, 0.5);
  if (!frame_max_strain_.empty()) {
    s.max_strain = *std::max_element(frame_max_strain_.begin(), frame_max_strain_.end());
  }
  s.max_strain_p99 = PercentileOf(frame_max_strain_, 0.99);
  s.mean_strain = Mean(frame_mean_strain_);
  if (skin_) {
    const double deepest =
        frame_penetration_.empty()
            ? 0.0
            : *std::max_element(frame_penetration_.begin(), frame_penetration_.end());
    s.penetration_max_mm = 1e3 * deepest;
    s.penetration_p99_mm = 1e3 * PercentileOf(frame_penetration_, 0.99);
  } else {
    s.penetration_unmeasured = unmeasured_;
  }
  if (options_.count_crossings) {
    s.crossing_edges_max =
        frame_crossings_.empty()
            ? 0
            : *std::max_element(frame_crossings_.begin(), frame_crossings_.end());
  }
  s.nan = nan_;
  s.steps_rolled_back = rolled_back_;
  s.steps = steps_;
  s.iterations_per_frame_mean =
      s.frames ? static_cast<double>(iterations_) / static_cast<double>(s.frames) : 0.0;
  return s;
}

}  // namespace costume::sim
