#include "sim_core/solver/strain_limit.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>

namespace costume::sim {

StrainLimiter::StrainLimiter(const ClothModel& model) {
  const std::vector<Spring>& springs = model.springs();
  for (std::size_t k = 0; k < springs.size(); ++k) {
    if (springs[k].kind == SpringKind::kBending) continue;  // bending springs fold, not stretch
    spring_.push_back(static_cast<int>(k));
    a_.push_back(springs[k].a);
    b_.push_back(springs[k].b);
    structural_.push_back(springs[k].kind == SpringKind::kStructural ? 1 : 0);
  }
  // Multi-source Dijkstra from every pinned particle over the structural springs.
  const int n = model.num_particles();
  std::vector<std::vector<std::pair<int, double>>> neighbours(n);
  for (const Spring& s : springs) {
    if (s.kind != SpringKind::kStructural) continue;
    neighbours[s.a].emplace_back(s.b, s.rest_length);
    neighbours[s.b].emplace_back(s.a, s.rest_length);
  }
  std::vector<double> distance(n, std::numeric_limits<double>::infinity());
  std::vector<int> anchor(n, -1);
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  for (int p : model.pinned()) {
    distance[p] = 0.0;
    anchor[p] = p;
    queue.emplace(0.0, p);
  }
  while (!queue.empty()) {
    const auto [d, i] = queue.top();
    queue.pop();
    if (d > distance[i]) continue;
    for (const auto& [j, length] : neighbours[i]) {
      if (d + length < distance[j]) {
        distance[j] = d + length;
        anchor[j] = anchor[i];
        queue.emplace(distance[j], j);
      }
    }
  }
  for (int i = 0; i < n; ++i) {
    if (anchor[i] >= 0 && anchor[i] != i) tethers_.push_back({i, anchor[i], distance[i]});
  }
  start_direction_ = Points::Zero(static_cast<Eigen::Index>(spring_.size()), 3);
  rest_.assign(spring_.size(), 0.0);
  target_.assign(spring_.size(), 0.0);
  w_.assign(model.num_particles(), 0.0);
}

void StrainLimiter::BeginStep(const Points& positions) {
  for (std::size_t k = 0; k < spring_.size(); ++k) {
    const Eigen::RowVector3d d = positions.row(b_[k]) - positions.row(a_[k]);
    const double length = d.norm();
    // A collapsed spring has no direction: its target is then its rest length.
    start_direction_.row(k) = length > 0.0 ? Eigen::RowVector3d(d / length)
                                           : Eigen::RowVector3d::Zero();
  }
  planes_.clear();
}

void StrainLimiter::SetTargets(const ClothModel& model, const StrainLimitSettings& settings,
                               const Points& positions) {
  const std::vector<Spring>& springs = model.springs();
  for (std::size_t k = 0; k < spring_.size(); ++k) {
    const double rest = springs[spring_[k]].rest_length;
    const double meant =
        start_direction_.row(k).dot(positions.row(b_[k]) - positions.row(a_[k]));
    const double target = std::max(rest, meant) + kFreeStretch * rest;
    rest_[k] = rest;
    target_[k] = structural_[k] ? std::min(target, (1.0 + settings.limit) * rest) : target;
  }
}

void StrainLimiter::SetCapTargets(const ClothModel& model, const StrainLimitSettings& settings) {
  const std::vector<Spring>& springs = model.springs();
  for (std::size_t k = 0; k < spring_.size(); ++k) {
    const double rest = springs[spring_[k]].rest_length;
    rest_[k] = rest;
    target_[k] = structural_[k] ? (1.0 + settings.limit) * rest
                                : std::numeric_limits<double>::infinity();
  }
}

void StrainLimiter::AddPlanes(std::span<const Contact> contacts) {
  for (const Contact& c : contacts) {
    if (std::isfinite(c.shell_offset)) planes_.push_back({c.particle, c.normal, c.shell_offset});
  }
}

void StrainLimiter::AddPlanes(std::span<const ShellPlane> planes) {
  planes_.insert(planes_.end(), planes.begin(), planes.end());
}

StrainLimitReport StrainLimiter::Limit(const ClothModel& model,
                                       const StrainLimitSettings& settings, ClothState& state,
                                       const std::vector<char>& fixed) {
  for (int i = 0; i < model.num_particles(); ++i) {
    const bool still = model.is_pinned()[i] || (!fixed.empty() && fixed[i]);
    w_[i] = still ? 0.0 : 1.0 / model.masses()[i];
  }
  Points& x = state.positions;
  Points& v = state.velocities;
  const auto keep_outside = [&] {
    for (const ShellPlane& plane : planes_) {
      if (w_[plane.particle] == 0.0) continue;
      const double below = plane.offset - x.row(plane.particle).dot(plane.normal);
      if (below > 0.0) x.row(plane.particle) += below * plane.normal.transpose();
    }
  };
  const auto keep_tethered = [&] {
    for (const Tether& t : tethers_) {
      if (w_[t.particle] == 0.0) continue;
      const Eigen::RowVector3d d = x.row(t.particle) - x.row(t.anchor);
      const double length = d.norm();
      const double longest = (1.0 + settings.limit) * t.rest;
      if (!(length > longest)) continue;
      const Eigen::RowVector3d u = d / length;
      x.row(t.particle) -= (length - longest) * u;
      const double separating = (v.row(t.particle) - v.row(t.anchor)).dot(u);
      if (separating > 0.0) v.row(t.particle) -= separating * u;
    }
  };
  StrainLimitReport report;
  for (int sweep = 0; sweep < settings.max_sweeps; ++sweep) {
    keep_tethered();
    keep_outside();
    double worst = 0.0;
    for (std::size_t k = 0; k < spring_.size(); ++k) {
      const int a = a_[k], b = b_[k];
      const Eigen::RowVector3d d = x.row(b) - x.row(a);
      const double length = d.norm();
      const double excess = length - target_[k];
      if (!(excess > 0.0)) continue;
      const double wa = w_[a], wb = w_[b];
      if (wa + wb == 0.0) continue;
      worst = std::max(worst, excess / rest_[k]);
      const Eigen::RowVector3d u = d / length;
      x.row(a) += (wa * excess / (wa + wb)) * u;
      x.row(b) -= (wb * excess / (wa + wb)) * u;
      const double separating = (v.row(b) - v.row(a)).dot(u);
      if (separating > 0.0) {
        v.row(a) += (wa * separating / (wa + wb)) * u;
        v.row(b) -= (wb * separating / (wa + wb)) * u;
      }
      ++report.corrections;
    }
    report.sweeps = sweep + 1;
    report.remaining = worst;
    if (worst <= settings.tolerance) break;
  }
  keep_outside();  // the obstacles have the last word within the sweeps
  return report;
}

}  // namespace costume::sim
