#include "frontend/picking.h"

#include <cmath>

namespace costume::frontend {
namespace {

/// Distance along the ray to triangle (a, b, c), or a negative value for a miss.
double RayTriangle(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& a,
                   const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d e1 = b - a;
  const Eigen::Vector3d e2 = c - a;
  const Eigen::Vector3d p = d.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-14) return -1.0;  // parallel (or degenerate triangle)
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = o - a;
  const double u = s.dot(p) * inv;
  if (u < 0.0 || u > 1.0) return -1.0;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = d.dot(q) * inv;
  if (v < 0.0 || u + v > 1.0) return -1.0;
  return e2.dot(q) * inv;
}

}  // namespace

std::optional<Hit> PickTriangles(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                 const std::vector<Eigen::Vector3f>& positions,
                                 const std::vector<std::uint32_t>& indices) {
  std::optional<Hit> best;
  const std::size_t n = positions.size();
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
    const std::uint32_t i = indices[t], j = indices[t + 1], k = indices[t + 2];
    if (i >= n || j >= n || k >= n) continue;
    const double distance =
        RayTriangle(origin, direction, positions[i].cast<double>(), positions[j].cast<double>(),
                    positions[k].cast<double>());
    if (distance < 0.0 || (best && distance >= best->distance)) continue;
    best = Hit{distance, origin + distance * direction, static_cast<int>(t / 3)};
  }
  return best;
}

std::optional<Eigen::Vector3d> RayPlane(const Eigen::Vector3d& origin,
                                        const Eigen::Vector3d& direction,
                                        const Eigen::Vector3d& plane_point,
                                        const Eigen::Vector3d& plane_normal) {
  const double denominator = plane_normal.dot(direction);
  if (std::abs(denominator) < 1e-12 * plane_normal.norm()) return std::nullopt;
  const double distance = plane_normal.dot(plane_point - origin) / denominator;
  if (!(distance >= 0.0) || !std::isfinite(distance)) return std::nullopt;
  return origin + distance * direction;
}

}  // namespace costume::frontend
