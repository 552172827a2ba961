#include "sim_core/cloth/cloth_model.h"

#include <cmath>
#include <set>
#include <utility>

#include "sim_core/common/input_error.h"

namespace costume::sim {

const char* SpringKindName(SpringKind kind) {
  switch (kind) {
    case SpringKind::kStructural: return "structural";
    case SpringKind::kShear: return "shear";
    case SpringKind::kBending: return "bending";
  }
  return "unknown";
}

namespace {

std::string Where(const ClothModelData& data) { return "cloth '" + data.name + "': "; }

void ValidateParticles(const ClothModelData& data) {
  const auto n = data.masses.size();
  if (n == 0) throw InputError(Where(data) + "has no particles (allowed: at least 1)");
  if (data.rest_positions.rows() != n || data.areas.size() != n || data.drag.size() != n) {
    throw InputError(Where(data) + "positions (" + std::to_string(data.rest_positions.rows()) +
                     "), masses (" + std::to_string(n) + ") and areas (" +
                     std::to_string(data.areas.size()) + ") must have one entry per particle");
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::string p = Where(data) + "particle " + std::to_string(i) + " ";
    for (int c = 0; c < 3; ++c) {
      RequireInRange(p + "position", data.rest_positions(i, c), -kMaxCoordinate, kMaxCoordinate,
                     "m");
    }
    RequirePositive(p + "mass", data.masses[i], "kg");
    RequireNonNegative(p + "area", data.areas[i], "m²");
    RequireNonNegative(p + "drag", data.drag[i], "N·s/m");
  }
}

void ValidateSpring(const ClothModelData& data, std::size_t index, const Spring& s) {
  const int n = static_cast<int>(data.masses.size());
  const std::string p = Where(data) + "spring " + std::to_string(index) + " (" +
                        SpringKindName(s.kind) + ") ";
  for (int end : {s.a, s.b}) {
    if (end < 0 || end >= n) {
      throw InputError(p + "particle index = " + std::to_string(end) +
                       " is out of range: allowed 0 to " + std::to_string(n - 1));
    }
  }
  if (s.a == s.b) {
    throw InputError(p + "joins particle " + std::to_string(s.a) +
                     " to itself: a spring needs two different particles");
  }
  RequireNonNegative(p + "stiffness", s.stiffness, "N/m");
  RequireNonNegative(p + "damping", s.damping, "N·s/m");
  RequirePositive(p + "rest_length", s.rest_length, "m");
}

void ValidateSprings(const ClothModelData& data) {
  std::set<std::pair<int, int>> seen;
  for (std::size_t k = 0; k < data.springs.size(); ++k) {
    const Spring& s = data.springs[k];
    ValidateSpring(data, k, s);
    if (!seen.insert(std::minmax(s.a, s.b)).second) {
      throw InputError(Where(data) + "spring " + std::to_string(k) + " duplicates another " +
                       "spring between particles " + std::to_string(s.a) + " and " +
                       std::to_string(s.b) + ": each pair may have one spring");
    }
  }
}

void ValidatePinsAndTriangles(const ClothModelData& data) {
  const int n = static_cast<int>(data.masses.size());
  std::set<int> pins;
  for (int pin : data.pinned) {
    if (pin < 0 || pin >= n) {
      throw InputError(Where(data) + "pinned particle index = " + std::to_string(pin) +
                       " is out of range: allowed 0 to " + std::to_string(n - 1));
    }
    if (!pins.insert(pin).second) {
      throw InputError(Where(data) + "particle " + std::to_string(pin) + " is pinned twice");
    }
  }
  for (std::size_t t = 0; t < data.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      const int v = data.triangles[t][c];
      if (v < 0 || v >= n) {
        throw InputError(Where(data) + "triangle " + std::to_string(t) + " vertex index = " +
                         std::to_string(v) + " is out of range: allowed 0 to " +
                         std::to_string(n - 1));
      }
    }
  }
}

}  // namespace

std::shared_ptr<const ClothModel> ClothModel::Create(ClothModelData data) {
  if (data.drag.size() == 0) data.drag = Eigen::VectorXd::Zero(data.masses.size());
  ValidateParticles(data);
  ValidateSprings(data);
  ValidatePinsAndTriangles(data);
  return std::shared_ptr<const ClothModel>(new ClothModel(std::move(data)));
}

ClothModel::ClothModel(ClothModelData data) : data_(std::move(data)) {
  is_pinned_.assign(data_.masses.size(), false);
  for (int pin : data_.pinned) is_pinned_[pin] = true;
}

std::shared_ptr<const ClothModel> ClothModel::WithRestLengths(
    const Eigen::VectorXd& rest_lengths) const {
  if (rest_lengths.size() != num_springs()) {
    throw InputError(Where(data_) + "rest_lengths has " + std::to_string(rest_lengths.size()) +
                     " entries; the model has " + std::to_string(num_springs()) + " springs");
  }
  ClothModelData copy = data_;
  for (int k = 0; k < num_springs(); ++k) copy.springs[k].rest_length = rest_lengths[k];
  return Create(std::move(copy));
}

}  // namespace costume::sim
