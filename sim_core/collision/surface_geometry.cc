#include "sim_core/collision/surface_geometry.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

namespace costume::sim {
namespace {

TrianglePoint Make(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   double wa, double wb, double wc, TriangleFeature feature) {
  TrianglePoint result;
  result.barycentric = Eigen::Vector3d(wa, wb, wc);
  result.point = wa * a + wb * b + wc * c;
  result.feature = feature;
  return result;
}

// Angle of the triangle at corner `at` between the edges to `u` and `w` [rad].
double CornerAngle(const Eigen::Vector3d& at, const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
  const Eigen::Vector3d e1 = u - at;
  const Eigen::Vector3d e2 = w - at;
  return std::atan2(e1.cross(e2).norm(), e1.dot(e2));
}

/// The cross product of triangle `tri`'s edges from its first corner in `vertices`: its
/// normal times twice its area. Every face normal is computed from it (Update,
/// VertexNormalOf), so each gives the same bits.
Eigen::Vector3d EdgeCross(const Points& vertices, const Eigen::Vector3i& tri) {
  const Eigen::Vector3d a = vertices.row(tri[0]).transpose();
  return (vertices.row(tri[1]).transpose() - a).cross(vertices.row(tri[2]).transpose() - a);
}

Eigen::Vector3d NormalisedOr(const Eigen::Vector3d& v, const Eigen::Vector3d& fallback) {
  const double norm = v.norm();
  return norm > 0.0 ? Eigen::Vector3d(v / norm) : fallback;
}

}  // namespace

TrianglePoint ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                     const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return Make(a, b, c, 1, 0, 0, TriangleFeature::kVertexA);
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return Make(a, b, c, 0, 1, 0, TriangleFeature::kVertexB);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return Make(a, b, c, 1 - v, v, 0, TriangleFeature::kEdgeAB);
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return Make(a, b, c, 0, 0, 1, TriangleFeature::kVertexC);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return Make(a, b, c, 1 - w, 0, w, TriangleFeature::kEdgeCA);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return Make(a, b, c, 0, 1 - w, w, TriangleFeature::kEdgeBC);
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return Make(a, b, c, 1, 0, 0, TriangleFeature::kVertexA);  // degenerate
  const double v = vb / sum;
  const double w = vc / sum;
  return Make(a, b, c, 1 - v - w, v, w, TriangleFeature::kFace);
}

SurfacePseudonormals::SurfacePseudonormals(int num_vertices,
                                           const std::vector<Eigen::Vector3i>& triangles)
    : triangles_(triangles),
      neighbours_(triangles.size(), {-1, -1, -1}),
      pieces_(triangles.size(), 0),
      face_normals_(triangles.size(), Eigen::Vector3d::UnitY()),
      double_areas_(triangles.size(), 0.0),
      vertex_normals_(num_vertices, Eigen::Vector3d::UnitY()) {
  BuildAdjacency();
  BuildPieces();
  corner_start_.assign(num_vertices + 1, 0);
  for (const Eigen::Vector3i& tri : triangles_) {
    for (int k = 0; k < 3; ++k) ++corner_start_[tri[k] + 1];
  }
  for (int v = 0; v < num_vertices; ++v) corner_start_[v + 1] += corner_start_[v];
  corners_.resize(3 * triangles_.size());
  std::vector<int> cursor(corner_start_.begin(), corner_start_.end() - 1);
  for (int t = 0; t < num_triangles(); ++t) {
    for (int k = 0; k < 3; ++k) corners_[cursor[triangles_[t][k]]++] = 3 * t + k;
  }
}

void SurfacePseudonormals::BuildAdjacency() {
  // Every directed edge (from, to) with the triangle and local edge using it, sorted: the
  // users of one edge are a run, found by binary search. (A map of vectors took most of a
  // MakeHuman body's construction in allocations.)
  struct DirectedEdge {
    int from, to, t, k;
    auto operator<=>(const DirectedEdge&) const = default;
  };
  const auto edge_less = [](const DirectedEdge& a, const DirectedEdge& b) {
    return std::pair(a.from, a.to) < std::pair(b.from, b.to);
  };
  std::vector<DirectedEdge> directed;
  directed.reserve(3 * triangles_.size());
  for (int t = 0; t < num_triangles(); ++t) {
    for (int k = 0; k < 3; ++k) {
      directed.push_back({triangles_[t][k], triangles_[t][(k + 1) % 3], t, k});
    }
  }
  std::sort(directed.begin(), directed.end());
  for (auto first = directed.cbegin(); first != directed.cend();) {
    const DirectedEdge edge = *first;
    const auto last = std::upper_bound(first, directed.cend(), edge, edge_less);
    const auto num_users = static_cast<std::size_t>(last - first);
    const auto [twin, twin_end] = std::equal_range(
        directed.cbegin(), directed.cend(), DirectedEdge{edge.to, edge.from, 0, 0}, edge_less);
    const auto num_twins = static_cast<std::size_t>(twin_end - twin);
    first = last;
    if (num_users == 1 && num_twins == 1) {
      neighbours_[edge.t][edge.k] = twin->t;
      continue;
    }
    if (edge.from > edge.to && num_twins > 0) continue;  // reported from the twin
    ++num_open_edges_;
    if (first_open_edge_.empty()) {
      first_open_edge_ = "edge (" + std::to_string(edge.from) + ", " + std::to_string(edge.to) +
                         ") used by " + std::to_string(num_users + num_twins) +
                         " triangle(s), " + std::to_string(num_users) + " in this direction";
    }
  }
}

void SurfacePseudonormals::BuildPieces() {
  std::fill(pieces_.begin(), pieces_.end(), -1);
  std::vector<int> stack;
  for (int seed = 0; seed < num_triangles(); ++seed) {
    if (pieces_[seed] >= 0) continue;
    pieces_[seed] = num_pieces_;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const int t = stack.back();
      stack.pop_back();
      for (int n : neighbours_[t]) {
        if (n >= 0 && pieces_[n] < 0) {
          pieces_[n] = num_pieces_;
          stack.push_back(n);
        }
      }
    }
    ++num_pieces_;
  }
}

void SurfacePseudonormals::Update(const Points& vertices, bool vertex_normals) {
  has_vertex_normals_ = vertex_normals;
  if (!vertex_normals) {
    for (int t = 0; t < num_triangles(); ++t) {
      const Eigen::Vector3d cross = EdgeCross(vertices, triangles_[t]);
      double_areas_[t] = cross.norm();
      if (double_areas_[t] > 0.0) face_normals_[t] = cross / double_areas_[t];
    }
    return;
  }
  std::fill(vertex_normals_.begin(), vertex_normals_.end(), Eigen::Vector3d::Zero());
  for (int t = 0; t < num_triangles(); ++t) {
    const Eigen::Vector3i& tri = triangles_[t];
    const Eigen::Vector3d a = vertices.row(tri[0]).transpose();
    const Eigen::Vector3d b = vertices.row(tri[1]).transpose();
    const Eigen::Vector3d c = vertices.row(tri[2]).transpose();
    const Eigen::Vector3d cross = EdgeCross(vertices, tri);
    double_areas_[t] = cross.norm();
    // A degenerate triangle contributes nothing to its vertices (its angles are 0 or π
    // with a meaningless normal); its own normal keeps the last good value.
    if (double_areas_[t] > 0.0) face_normals_[t] = cross / double_areas_[t];
    const Eigen::Vector3d& n = face_normals_[t];
    if (double_areas_[t] == 0.0) continue;
    vertex_normals_[tri[0]] += CornerAngle(a, b, c) * n;
    vertex_normals_[tri[1]] += CornerAngle(b, c, a) * n;
    vertex_normals_[tri[2]] += CornerAngle(c, a, b) * n;
  }
  for (Eigen::Vector3d& n : vertex_normals_) n = NormalisedOr(n, Eigen::Vector3d::UnitY());
}

const std::array<Eigen::Vector3d, 4>& WindingRayDirections() {
  static const std::array<Eigen::Vector3d, 4> directions = {
      Eigen::Vector3d(1, 2, 3).normalized(), Eigen::Vector3d(-4, 1, 4).normalized(),
      Eigen::Vector3d(3, -7.5, 0.1).normalized(), Eigen::Vector3d(-2, -1, -4).normalized()};
  return directions;
}

const std::array<Eigen::Vector3d, kNumExitRays>& ExitRayDirections() {
  static const std::array<Eigen::Vector3d, kNumExitRays> directions = [] {
    std::array<Eigen::Vector3d, kNumExitRays> list;
    int k = 0;
    for (int axis = 0; axis < 3; ++axis) {
      for (double sign : {1.0, -1.0}) list[k++] = sign * Eigen::Vector3d::Unit(axis);
    }
    for (double x : {1.0, -1.0}) {
      for (double y : {1.0, -1.0}) {
        for (double z : {1.0, -1.0}) list[k++] = Eigen::Vector3d(x, y, z);
      }
    }
    for (Eigen::Vector3d& d : list) d = (d + Eigen::Vector3d(3e-4, 7e-4, 5e-4)).normalized();
    return list;
  }();
  return directions;
}

Crossing RayCrossing(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                     const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  constexpr double kEdgeTolerance = 1e-9;
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d p = direction.cross(e2);
  // det = −direction·(e1 × e2): negative where the ray leaves through the outside.
  const double det = e1.dot(p);
  const Eigen::Vector3d s = origin - a;
  const double scale = e1.norm() * e2.norm();
  const double length = std::sqrt(scale);
  if (std::abs(det) <= kEdgeTolerance * scale) {
    // Parallel to the plane: no crossing, unless the ray runs in it.
    const Eigen::Vector3d normal = e1.cross(e2);
    const double norm = normal.norm();
    return norm > 0.0 && std::abs(normal.dot(s)) > kEdgeTolerance * norm * length
               ? Crossing::kNone
               : Crossing::kUncertain;
  }
  const double u = s.dot(p) / det;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = direction.dot(q) / det;
  if (u < -kEdgeTolerance || v < -kEdgeTolerance || u + v > 1.0 + kEdgeTolerance) {
    return Crossing::kNone;
  }
  const double t = e2.dot(q) / det;
  if (t < -kEdgeTolerance * length) return Crossing::kNone;
  if (u < kEdgeTolerance || v < kEdgeTolerance || u + v > 1.0 - kEdgeTolerance ||
      t <= kEdgeTolerance * length) {
    return Crossing::kUncertain;
  }
  return det < 0.0 ? Crossing::kExit : Crossing::kEntry;
}

SurfaceSide SideOf(const Eigen::Vector3d& point, const Eigen::Vector3d& closest,
                   const Eigen::Vector3d& pseudonormal) {
  const Eigen::Vector3d offset = point - closest;
  const double distance = offset.norm();
  const bool inside = offset.dot(pseudonormal) < 0.0;
  SurfaceSide side;
  side.signed_distance = inside ? -distance : distance;
  side.normal =
      distance > 0.0 ? Eigen::Vector3d((inside ? -offset : offset) / distance) : pseudonormal;
  return side;
}

Eigen::Vector3d SurfacePseudonormals::VertexNormal(int vertex, const Points& vertices) const {
  return AngleWeightedNormal(vertex, vertices, /*own_faces=*/false);
}

Eigen::Vector3d SurfacePseudonormals::VertexNormalOf(int vertex, const Points& vertices) const {
  return AngleWeightedNormal(vertex, vertices, /*own_faces=*/true);
}

Eigen::Vector3d SurfacePseudonormals::AngleWeightedNormal(int vertex, const Points& vertices,
                                                          bool own_faces) const {
  // Update's sum, term by term in the same order (by triangle), each face normal as
  // Update computes it, so the same bits.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int j = corner_start_[vertex]; j < corner_start_[vertex + 1]; ++j) {
    const int t = corners_[j] / 3;
    const int k = corners_[j] % 3;
    const Eigen::Vector3i& tri = triangles_[t];
    Eigen::Vector3d normal = face_normals_[t];
    if (own_faces) {
      const Eigen::Vector3d cross = EdgeCross(vertices, tri);
      const double double_area = cross.norm();
      if (double_area == 0.0) continue;
      normal = cross / double_area;
    } else if (double_areas_[t] == 0.0) {
      continue;
    }
    sum += CornerAngle(vertices.row(tri[k]).transpose(), vertices.row(tri[(k + 1) % 3]).transpose(),
                       vertices.row(tri[(k + 2) % 3]).transpose()) *
           normal;
  }
  return NormalisedOr(sum, Eigen::Vector3d::UnitY());
}

Eigen::Vector3d SurfacePseudonormals::Of(int triangle, TriangleFeature feature,
                                         const Points& vertices) const {
  if (has_vertex_normals_) return Of(triangle, feature);
  const Eigen::Vector3i& tri = triangles_[triangle];
  switch (feature) {
    case TriangleFeature::kVertexA: return VertexNormal(tri[0], vertices);
    case TriangleFeature::kVertexB: return VertexNormal(tri[1], vertices);
    case TriangleFeature::kVertexC: return VertexNormal(tri[2], vertices);
    default: return Of(triangle, feature);
  }
}

Eigen::Vector3d SurfacePseudonormals::Of(int triangle, TriangleFeature feature) const {
  const Eigen::Vector3i& tri = triangles_[triangle];
  const Eigen::Vector3d& n = face_normals_[triangle];
  int edge = -1;
  switch (feature) {
    case TriangleFeature::kFace: return n;
    case TriangleFeature::kVertexA: return vertex_normals_[tri[0]];
    case TriangleFeature::kVertexB: return vertex_normals_[tri[1]];
    case TriangleFeature::kVertexC: return vertex_normals_[tri[2]];
    case TriangleFeature::kEdgeAB: edge = 0; break;
    case TriangleFeature::kEdgeBC: edge = 1; break;
    case TriangleFeature::kEdgeCA: edge = 2; break;
  }
  const int other = neighbours_[triangle][edge];
  if (other < 0) return n;  // a hole's rim: the one face there is
  return NormalisedOr(n + face_normals_[other], n);
}

}  // namespace costume::sim
