#include "tools/regions_comparison.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/skeleton.h"
#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/cloth/material.h"
#include "sim_core/collision/mesh_collider.h"

namespace costume::tools {

namespace {

using namespace costume::sim;
using nlohmann::json;
using Settings = RegionsComparisonSettings;

/// A box avatar (one joint) whose top face is y = 0: half extents (a, b, a) around
/// (0, −b, 0), every face a grid of about `cell` spacing, welded, outward winding.
std::shared_ptr<const Avatar> BoxAvatar(double a, double b, double cell) {
  std::map<std::array<long long, 3>, int> index;
  std::vector<Eigen::Vector3d> positions;
  auto vertex = [&](const Eigen::Vector3d& x) {
    const std::array<long long, 3> key = {std::llround(x.x() * 1e9), std::llround(x.y() * 1e9),
                                          std::llround(x.z() * 1e9)};
    const auto [it, added] = index.emplace(key, static_cast<int>(positions.size()));
    if (added) positions.push_back(x);
    return it->second;
  };
  const Eigen::Vector3d center(0.0, -b, 0.0), half(a, b, a);
  AvatarData data;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {1, -1}) {
      int j = (axis + 1) % 3, k = (axis + 2) % 3;
      if (sign < 0) std::swap(j, k);  // keeps j × k pointing out of the face
      const int na = std::max(1, static_cast<int>(std::lround(2 * half[j] / cell)));
      const int nb = std::max(1, static_cast<int>(std::lround(2 * half[k] / cell)));
      auto at = [&](int u, int w) {
        Eigen::Vector3d x;
        x[axis] = sign * half[axis];
        x[j] = -half[j] + 2.0 * half[j] * u / na;
        x[k] = -half[k] + 2.0 * half[k] * w / nb;
        return vertex(center + x);
      };
      for (int u = 0; u < na; ++u) {
        for (int w = 0; w < nb; ++w) {
          const int v00 = at(u, w), v10 = at(u + 1, w), v11 = at(u + 1, w + 1);
          const int v01 = at(u, w + 1);
          data.triangles.emplace_back(v00, v10, v11);
          data.triangles.emplace_back(v00, v11, v01);
        }
      }
    }
  }
  Joint root;
  root.name = "root";
  data.name = "box";
  data.skeleton = Skeleton::Create("one joint", {root});
  const auto n = static_cast<Eigen::Index>(positions.size());
  data.rest_vertices.resize(n, 3);
  for (Eigen::Index v = 0; v < n; ++v) data.rest_vertices.row(v) = positions[v];
  data.influence_joints.setConstant(n, kMaxInfluences, -1);
  data.influence_joints.col(0).setZero();
  data.influence_weights.setZero(n, kMaxInfluences);
  data.influence_weights.col(0).setOnes();
  return Avatar::Create(std::move(data));
}

/// The sheet, centred, 2 mm above y = 0.
std::shared_ptr<const ClothModel> Sheet(const Settings& s) {
  LatticePanel panel;
  panel.rows = panel.cols = s.n;
  panel.width = panel.height = s.sheet_size;
  panel.origin = Eigen::Vector3d(-s.sheet_size / 2, 0.002, -s.sheet_size / 2);
  return ClothModel::Create(BuildLatticePanel(panel, NamedMaterial("stiff_cotton"), "sheet"));
}

/// Tight zig-zag folds: consecutive columns alternate between 2 mm and 2 mm + fold height
/// above the top, the columns' spacing shrunk so each lattice edge keeps its length, plus
/// 1 mm of crumpling noise.
Points Folded(const ClothModel& sheet, const Settings& s) {
  std::mt19937 rng(s.seed);
  std::uniform_real_distribution<double> noise(-0.001, 0.001);
  const double spacing = s.sheet_size / (s.n - 1);
  const double step = std::sqrt(std::max(spacing * spacing - s.fold_height * s.fold_height,
                                         0.04 * spacing * spacing));
  Points x = sheet.rest_positions();
  for (int p = 0; p < sheet.num_particles(); ++p) {
    const int j = p % sheet.lattice_cols();
    x(p, 0) = step * (j - 0.5 * (s.n - 1)) + noise(rng);
    x(p, 1) = 0.002 + (j % 2) * s.fold_height + std::abs(noise(rng));
    x(p, 2) += noise(rng);
  }
  return x;
}

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t m = values.size() / 2;
  return values.size() % 2 ? values[m] : 0.5 * (values[m - 1] + values[m]);
}


json RunCase(const std::shared_ptr<const Avatar>& avatar, const ClothModel& sheet,
             const Points& x, const Settings& s) {
  const double h = 1.0 / 60.0, margin = 0.003;
  const Points v = Points::Zero(x.rows(), 3);
  std::vector<std::unique_ptr<MeshCollider>> colliders;
  for (int mode = 0; mode < 3; ++mode) {
    MeshCollisionOptions options;
    options.cloth_regions = mode > 0;
    options.cloth_adaptive = mode == 2;
    options.max_penetration = s.max_penetration;
    options.reuse_bounds = s.reuse_bounds;
    colliders.push_back(std::make_unique<MeshCollider>(avatar, BodyCollisionSettings{}, options));
    colliders.back()->SetCloth(sheet);
    colliders.back()->Update({Eigen::Isometry3d::Identity()}, avatar->rest_vertices(), h);
  }
  std::vector<Contact> contacts;
  contacts.reserve(x.rows());
  std::array<std::vector<double>, 3> ms;
  std::array<std::size_t, 3> num_contacts{};
  // Blocks of `block` calls per mode, the modes taking turns: a collider's data (several
  // MB for this body) stays in cache within its block, as in a simulation with one
  // collider, while the turns still spread the machine's noise over the modes.
  const int num_blocks = (s.reps + s.block - 1) / s.block;
  for (int b = -1; b < num_blocks; ++b) {  // block −1 warms up (first-call allocations)
    for (int k = 0; k < 3; ++k) {
      const int mode = (b + 3 + k) % 3;
      if (s.only >= 0 && mode != s.only) continue;
      for (int call = 0; call < (b < 0 ? 1 : s.block); ++call) {
        contacts.clear();
        const auto start = std::chrono::steady_clock::now();
        colliders[mode]->FindContacts(x, v, h, margin, contacts);
        const auto stop = std::chrono::steady_clock::now();
        if (b >= 0 && call > 0) {  // the block's first call refills the cache
          ms[mode].push_back(std::chrono::duration<double, std::milli>(stop - start).count());
        }
        num_contacts[mode] = contacts.size();
      }
    }
  }
  json out;
  for (int mode = 0; mode < 3; ++mode) {
    if (s.only >= 0 && mode != s.only) continue;
    out[kRegionModes[mode]] = {{"median_ms", Median(ms[mode])},
                         {"num_tests", colliders[mode]->stats().num_tests},
                         {"broad_phase_queries", colliders[mode]->num_broad_phase_queries()},
                         {"num_contacts", num_contacts[mode]}};
  }
  if (s.only >= 0) return out;  // the comparisons need all three
  auto saving = [&](int mode, int against, const char* key) {
    const double a = out[kRegionModes[mode]][key].get<double>();
    const double b = out[kRegionModes[against]][key].get<double>();
    return 100.0 * (1.0 - a / b);
  };
  out["saving_percent"] = {
      {"adaptive_vs_off",
       {{"tests", saving(2, 0, "num_tests")}, {"time", saving(2, 0, "median_ms")}}},
      {"fixed_vs_off", {{"tests", saving(1, 0, "num_tests")}, {"time", saving(1, 0, "median_ms")}}},
      {"adaptive_vs_fixed",
       {{"tests", saving(2, 1, "num_tests")}, {"time", saving(2, 1, "median_ms")}}}};
  out["same_contact_count"] =
      num_contacts[0] == num_contacts[1] && num_contacts[0] == num_contacts[2];
  const ClothRegions& regions = *colliders[2]->cloth_regions();
  out["cloth_base_regions"] = regions.num_base_regions();
  return out;
}

}  // namespace

json CompareClothRegions(const RegionsComparisonSettings& s, const std::string& sheet_case) {
  const auto avatar = BoxAvatar(s.box_size / 2, 0.2, s.cell);
  const auto sheet = Sheet(s);
  json out;
  out["avatar_triangles"] = avatar->triangles().size();
  out["sheet_particles"] = sheet->num_particles();
  out["reps"] = s.reps;
  out["block"] = s.block;
  out["max_penetration"] = s.max_penetration;
  out["reuse_bounds"] = s.reuse_bounds;
  if (sheet_case != "folded") out["flat"] = RunCase(avatar, *sheet, sheet->rest_positions(), s);
  if (sheet_case != "flat") out["folded"] = RunCase(avatar, *sheet, Folded(*sheet, s), s);
  return out;
}

}  // namespace costume::tools
