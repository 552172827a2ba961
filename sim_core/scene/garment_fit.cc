#include "sim_core/scene/garment_fit.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "sim_core/collision/mesh_distance.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

/// How deep inside the skin a vertex is still seen (and pushed out) [m]: deeper than this,
/// the nearest skin may be another limb's.
constexpr double kReach = 0.1;
/// Push-and-smooth rounds; the displacements settle in a few.
constexpr int kRounds = 8;
/// Smoothing sweeps per round: how many rings of neighbours a push spreads over.
constexpr int kSweeps = 3;

std::vector<std::vector<int>> Neighbours(const SurfaceMesh& mesh) {
  std::vector<std::vector<int>> neighbours(mesh.vertices.rows());
  for (const std::vector<int>& face : mesh.faces) {
    for (std::size_t k = 0; k < face.size(); ++k) {
      const int a = face[k], b = face[(k + 1) % face.size()];
      neighbours[a].push_back(b);
      neighbours[b].push_back(a);
    }
  }
  for (std::vector<int>& list : neighbours) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  return neighbours;
}

/// Moves each vertex nearer than `clearance` to the skin out to it; returns how many moved.
int Push(const MeshDistance& skin, double clearance, Points& x) {
  int moved = 0;
  for (Eigen::Index v = 0; v < x.rows(); ++v) {
    const SurfaceDistance q = skin.Query(x.row(v).transpose(), kReach);
    if (!(q.signed_distance < clearance)) continue;  // +inf: beyond reach
    x.row(v) += (clearance - q.signed_distance) * q.normal.transpose();
    ++moved;
  }
  return moved;
}

/// Replaces each displacement from `start` by the mean of its own and its neighbours'.
void Smooth(const std::vector<std::vector<int>>& neighbours, const Points& start, Points& x) {
  Points moved = x - start;
  for (int sweep = 0; sweep < kSweeps; ++sweep) {
    Points next = moved;
    for (Eigen::Index v = 0; v < moved.rows(); ++v) {
      for (int n : neighbours[v]) next.row(v) += moved.row(n);
      next.row(v) /= static_cast<double>(neighbours[v].size() + 1);
    }
    moved = std::move(next);
  }
  x = start + moved;
}

}  // namespace

SurfaceMesh FitOutsideBody(const SurfaceMesh& mesh, const Points& body_vertices,
                           const std::vector<Eigen::Vector3i>& body_triangles, double clearance,
                           GarmentFitReport* report) {
  RequireNonNegative(mesh.source + ": fit clearance", clearance, "m");
  const MeshDistance skin(mesh.source + ": body", body_vertices, body_triangles);
  GarmentFitReport result;
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    const double d = skin.SignedDistance(mesh.vertices.row(v).transpose(), kReach);
    result.num_too_close += d < clearance ? 1 : 0;
    result.max_depth_before = std::max(result.max_depth_before, std::isfinite(d) ? -d : 0.0);
  }
  const std::vector<std::vector<int>> neighbours = Neighbours(mesh);
  SurfaceMesh fitted = mesh;
  for (int round = 0; round < kRounds && Push(skin, clearance, fitted.vertices) > 0; ++round) {
    Smooth(neighbours, mesh.vertices, fitted.vertices);
  }
  Push(skin, clearance, fitted.vertices);
  result.max_move = (fitted.vertices - mesh.vertices).rowwise().norm().maxCoeff();
  result.min_distance_after = kReach;
  for (Eigen::Index v = 0; v < fitted.vertices.rows(); ++v) {
    result.min_distance_after = std::min(
        result.min_distance_after, skin.SignedDistance(fitted.vertices.row(v).transpose(), kReach));
  }
  if (report) *report = result;
  return fitted;
}

std::vector<Eigen::Vector3d> WaistbandPoints(const SurfaceMesh& mesh, double height, double band) {
  std::map<std::pair<int, int>, int> uses;
  for (const std::vector<int>& face : mesh.faces) {
    for (std::size_t k = 0; k < face.size(); ++k) {
      ++uses[std::minmax(face[k], face[(k + 1) % face.size()])];
    }
  }
  std::vector<int> parent(mesh.vertices.rows());
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  std::vector<bool> on_boundary(mesh.vertices.rows(), false);
  for (const auto& [edge, count] : uses) {
    if (count != 1) continue;
    on_boundary[edge.first] = on_boundary[edge.second] = true;
    parent[root(edge.first)] = root(edge.second);
  }
  std::map<int, std::vector<int>> loops;
  for (int v = 0; v < static_cast<int>(on_boundary.size()); ++v) {
    if (on_boundary[v]) loops[root(v)].push_back(v);
  }
  std::vector<Eigen::Vector3d> points;
  for (const auto& [id, loop] : loops) {
    double mean = 0.0;
    for (int v : loop) mean += mesh.vertices(v, 1) / static_cast<double>(loop.size());
    if (std::abs(mean - height) > band) continue;
    for (int v : loop) points.push_back(mesh.vertices.row(v).transpose());
  }
  return points;
}

}  // namespace costume::sim
