#include "sim_core/collision/superquadric_collider.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/surface_geometry.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

/// Floor of the ray/skin-normal cosine: a ray grazing the skin would otherwise turn a
/// millimetre of thickness into metres of radial shell.
constexpr double kMinSkinCosine = 0.1;

/// Per map drawing, the most rays whose first exit leads into skin again that are followed
/// to where they leave the skin for good, and the most crossings followed along each
/// (MarkFoldedRays, ResolveFoldedRays); the rest keep their first exit.
constexpr int kMaxFoldedRays = 512;
constexpr int kMaxCrossingsPerRay = 8;

using SegmentGroups = std::array<std::vector<int>, kNumHAnimJoints>;

SegmentGroups GroupVertices(const Avatar& avatar) {
  SegmentGroups groups;
  const auto& segments = avatar.vertex_segments();
  for (int v = 0; v < avatar.num_vertices(); ++v) {
    if (segments[v]) groups[static_cast<int>(*segments[v])].push_back(v);
  }
  return groups;
}

/// Rest vertices `group` of `avatar` moved by `to_frame` (world → the frame wanted).
Points VerticesIn(const Avatar& avatar, const std::vector<int>& group,
                  const Eigen::Isometry3d& to_frame) {
  Points points(static_cast<Eigen::Index>(group.size()), 3);
  for (std::size_t i = 0; i < group.size(); ++i) {
    points.row(i) = (to_frame * avatar.rest_vertices().row(group[i]).transpose()).transpose();
  }
  return points;
}

void ValidateOptions(const SuperquadricColliderOptions& options, const std::string& where) {
  if (options.min_vertices_per_segment < 11) {
    throw InputError(where + ": min_vertices_per_segment " +
                     std::to_string(options.min_vertices_per_segment) + " (allowed: >= 11)");
  }
  // Below 2 mm a torso's map would hold hundreds of thousands of nodes.
  RequireInRange(where + ": map_spacing", options.map_spacing, 0.002, 0.2, "m");
  RequireInRange(where + ": map_cache_quantum", options.map_cache_quantum, 1e-9, 0.001, "m");
}

std::vector<SegmentSuperquadricFit> FitGroups(const Avatar& avatar, const SegmentGroups& groups,
                                              const SuperquadricColliderOptions& options) {
  std::vector<SegmentSuperquadricFit> fits;
  for (HAnimJoint segment : AllHAnimJoints()) {
    const std::vector<int>& group = groups[static_cast<int>(segment)];
    if (group.empty()) continue;
    SegmentSuperquadricFit fit;
    fit.segment = segment;
    fit.joint = avatar.skeleton().Find(segment);
    fit.num_vertices = static_cast<int>(group.size());
    fit.fitted = fit.num_vertices >= options.min_vertices_per_segment;
    if (fit.fitted) {
      const Eigen::Isometry3d to_joint = avatar.skeleton().rest_world()[fit.joint].inverse();
      fit.fit = FitSuperquadric(
          VerticesIn(avatar, group, to_joint),
          "avatar '" + avatar.name() + "' segment " + std::string(HAnimName(segment)), options.fit);
    }
    fits.push_back(fit);
  }
  return fits;
}

// ---- distance map: a cube map of rays ------------------------------------------------------

/// The face of the box [−1, 1]³ through which the ray from the origin through the scaled
/// point `p` = (x/a1, y/a2, z/a3) leaves, and the in-face coordinates s = p_j/|p_i|,
/// t = p_k/|p_i| ∈ [−1, 1] (i the face's axis, j = (i+1)%3, k = (i+2)%3). False at the
/// origin, which has no ray.
bool LocateOnBox(const Eigen::Vector3d& p, int& face, double& s, double& t) {
  const double ax = std::abs(p.x()), ay = std::abs(p.y()), az = std::abs(p.z());
  const int i = ax >= ay ? (ax >= az ? 0 : 2) : (ay >= az ? 1 : 2);
  const double w = i == 0 ? ax : (i == 1 ? ay : az);
  if (!(w > 0.0)) return false;
  face = 2 * i + (p[i] < 0.0 ? 1 : 0);
  s = p[(i + 1) % 3] / w;
  t = p[(i + 2) % 3] / w;
  return true;
}

/// A map cell whose nodes' predictions of the skin's radius differ by more than this many
/// times the node spacing straddles a silhouette.
constexpr double kSilhouetteSlope = 3.0;

/// The node grid on the bounding box's faces: rays, the superquadric's radius along each,
/// the faces' node tables and the node adjacency. The skin fields start on the
/// superquadric itself. `extent` [m], the half sizes of the box the skin fills in the
/// superquadric's frame, sets the node counts, so nodes lie about `spacing` apart on the
/// skin even where it is far from a small superquadric.
SkinDistanceMap MakeMapGrid(const Superquadric& sq, const Eigen::Vector3d& extent,
                            double spacing) {
  SkinDistanceMap map;
  const Eigen::Vector3d size(sq.a1, sq.a2, sq.a3);
  const auto& n = map.intervals;
  for (int a = 0; a < 3; ++a) {
    const double side = 2.0 * std::max(size[a], extent[a]);
    map.intervals[a] = std::max(2, static_cast<int>(std::ceil(side / spacing)));
  }
  // Nodes are the lattice points on the boundary of [0, n0]×[0, n1]×[0, n2], so faces
  // share their edge and corner nodes.
  std::vector<int> lattice((n[0] + 1) * (n[1] + 1) * (n[2] + 1), -1);
  for (int f = 0; f < 6; ++f) {
    const int i = f / 2, j = (i + 1) % 3, k = (i + 2) % 3;
    std::vector<int>& table = map.face_nodes[f];
    table.resize((n[j] + 1) * (n[k] + 1));
    for (int u = 0; u <= n[j]; ++u) {
      for (int v = 0; v <= n[k]; ++v) {
        std::array<int, 3> g{};
        g[i] = f % 2 == 0 ? n[i] : 0;
        g[j] = u;
        g[k] = v;
        int& node = lattice[(g[0] * (n[1] + 1) + g[1]) * (n[2] + 1) + g[2]];
        if (node < 0) {
          node = map.num_nodes();
          Eigen::Vector3d box;
          for (int a = 0; a < 3; ++a) box[a] = size[a] * (-1.0 + 2.0 * g[a] / n[a]);
          map.ray.push_back(box.normalized());
          map.box_length.push_back(box.norm());
          map.surface_radius.push_back(box.norm() *
                                       std::pow(InsideOutside(sq, box), -0.5 * sq.e1));
        }
        table[u * (n[k] + 1) + v] = node;
      }
    }
  }
  std::vector<std::vector<int>> adjacent(map.num_nodes());
  for (int f = 0; f < 6; ++f) {
    const int i = f / 2, nj = n[(i + 1) % 3], nk = n[(i + 2) % 3];
    const auto at = [&](int u, int v) { return map.face_nodes[f][u * (nk + 1) + v]; };
    for (int u = 0; u <= nj; ++u) {
      for (int v = 0; v <= nk; ++v) {
        std::vector<int>& list = adjacent[at(u, v)];
        const int steps[4][2] = {{u - 1, v}, {u + 1, v}, {u, v - 1}, {u, v + 1}};
        for (const auto& [su, sv] : steps) {
          if (su < 0 || su > nj || sv < 0 || sv > nk) continue;
          if (std::find(list.begin(), list.end(), at(su, sv)) == list.end()) {
            list.push_back(at(su, sv));
          }
        }
      }
    }
  }
  map.neighbour_start.push_back(0);
  for (const std::vector<int>& list : adjacent) {
    map.neighbours.insert(map.neighbours.end(), list.begin(), list.end());
    map.neighbour_start.push_back(static_cast<int>(map.neighbours.size()));
  }
  for (int f = 0; f < 6; ++f) {
    map.face_offset[f] = map.num_face_points;
    map.num_face_points += static_cast<int>(map.face_nodes[f].size());
  }
  map.silhouette_jump = kSilhouetteSlope * spacing;
  map.spacing = spacing;
  map.size = size;
  return map;
}

/// A stored node's skin radius [m] for its map's radius step [m], whether it is capped (its
/// ray saw no skin), and its unit normal.
double NodeRadius(const StoredMapNode& node, double step) { return std::abs(node.radius) * step; }
bool NodeCapped(const StoredMapNode& node) { return node.radius < 0; }
Eigen::Vector3d NodeNormal(const StoredMapNode& node) {
  return Eigen::Vector3d(node.normal[0], node.normal[1], node.normal[2]) *
         (1.0 / StoredMapNode::kNormalScale);
}

/// The skin's radius along the unit ray `d` as a node of radius `radius` [m] on the unit ray
/// `ray` predicts it: where `d` meets the skin's tangent plane at the node (its own radius
/// where that plane nearly contains `d`) [m].
double PlaneRadius(const StoredMapNode& node, double radius, const Eigen::Vector3d& ray,
                   const Eigen::Vector3d& d) {
  const Eigen::Vector3d normal = NodeNormal(node);
  const double cosine = normal.dot(d);
  return cosine > kMinSkinCosine ? radius * normal.dot(ray) / cosine : radius;
}

/// The map of `segment` read on the unit ray `d` (superquadric frame): the skin's radius
/// [m] and its (unnormalised) normal, bilinear in the four nodes around `d`.
void LookUp(const SuperquadricSegment& segment, const Eigen::Vector3d& d, double& radius,
            Eigen::Vector3d& normal, bool& capped, bool& blind) {
  const SkinDistanceMap& map = segment.map;
  int face = 0;
  double s = 0.0, t = 0.0;
  LocateOnBox(d.cwiseProduct(segment.inverse_size), face, s, t);
  const int i = face / 2, nj = map.intervals[(i + 1) % 3], nk = map.intervals[(i + 2) % 3];
  const double fu = 0.5 * (s + 1.0) * nj, fv = 0.5 * (t + 1.0) * nk;
  const int u = std::clamp(static_cast<int>(fu), 0, nj - 1);
  const int v = std::clamp(static_cast<int>(fv), 0, nk - 1);
  const double wu = fu - u, wv = fv - v;
  // The face's grid points are stored row by row: the cell's four nodes are two pairs of
  // neighbours in memory.
  const int index = u * (nk + 1) + v;
  const int at[4] = {index, index + 1, index + nk + 1, index + nk + 2};
  const StoredMapNode* face_nodes = segment.nodes + map.face_offset[face];
  const StoredMapNode* n[4] = {face_nodes + at[0], face_nodes + at[1], face_nodes + at[2],
                               face_nodes + at[3]};
  const double step = segment.radius_step;
  const double r[4] = {NodeRadius(*n[0], step), NodeRadius(*n[1], step),
                       NodeRadius(*n[2], step), NodeRadius(*n[3], step)};
  if (std::max({r[0], r[1], r[2], r[3]}) - std::min({r[0], r[1], r[2], r[3]}) >
      map.silhouette_jump) {
    // The radii jump across the cell: either the ray grazes the skin (a leg's taper seen
    // from the calf's centre), and each node's tangent plane predicts the others' radii, or
    // the cell straddles a silhouette seen from the centre, some rays leaving the skin near,
    // others passing it and leaving far beyond. Blending those would raise a shell in the
    // air between (the crease of a hip over a thigh): the near skin holds. (The radius of
    // the node nearest the ray instead left the skin as near at the crease but made the
    // shell a step that snagged cloth: 280 % strain on the walk.)
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    int nearest = 0;
    const std::vector<int>& table = map.face_nodes[face];
    for (int k = 0; k < 4; ++k) {
      const double predicted = PlaneRadius(*n[k], r[k], map.ray[table[at[k]]], d);
      hi = std::max(hi, predicted);
      if (predicted < lo) lo = predicted, nearest = k;
    }
    if (hi - lo > map.silhouette_jump) {
      radius = lo;
      normal = NodeNormal(*n[nearest]);
      capped = blind = NodeCapped(*n[nearest]);
      return;
    }
  }
  const bool c[4] = {NodeCapped(*n[0]), NodeCapped(*n[1]), NodeCapped(*n[2]), NodeCapped(*n[3])};
  const int num_capped = c[0] + c[1] + c[2] + c[3];
  capped = num_capped > 0;
  blind = num_capped == 4;
  double w[4] = {(1 - wu) * (1 - wv), (1 - wu) * wv, wu * (1 - wv), wu * wv};
  // A capped node's radius is the reach, not skin: where nodes around it saw skin, they
  // alone are blended (blending the reach in raised a thigh's shell 1.6 cm out of
  // MakeHuman's hip).
  double seen = 0.0;
  for (int k = 0; k < 4; ++k) seen += c[k] ? 0.0 : w[k];
  if (capped && !blind && seen > 0.0) {
    for (int k = 0; k < 4; ++k) w[k] = c[k] ? 0.0 : w[k] / seen;
  }
  radius = w[0] * r[0] + w[1] * r[1] + w[2] * r[2] + w[3] * r[3];
  normal = w[0] * NodeNormal(*n[0]) + w[1] * NodeNormal(*n[1]) + w[2] * NodeNormal(*n[2]) +
           w[3] * NodeNormal(*n[3]);
}

/// The quadratic (6-node Lagrange) interpolation of a triangle's burial samples at the
/// barycentric point (l0, l1, l2), l summing to 1.
double InterpolateBurial(const std::array<double, 6>& b, double l0, double l1, double l2) {
  return b[0] * l0 * (2 * l0 - 1) + b[1] * l1 * (2 * l1 - 1) + b[2] * l2 * (2 * l2 - 1) +
         4 * (b[3] * l1 * l2 + b[4] * l2 * l0 + b[5] * l0 * l1);
}

/// Whether skin triangle `triangle` (corners in the superquadric frame) can stop a ray
/// within `reach`, with its normal (unnormalised) and plane: normal·corner, > 0 when the
/// centre sees the triangle's outside (counter-clockwise from outside), so rays through it
/// leave the skin, < 0 when they enter it. A triangle seen edge on stops nothing; nor does
/// one whose points or whose plane lie beyond the reach, where every ray stops anyway.
bool TriangleWithinReach(double reach, int triangle, const SegmentSkin& skin,
                         Eigen::Vector3d& normal, double& plane) {
  const Eigen::Vector3i& corners = skin.triangles[triangle];
  // Every point of the triangle is at least its nearest corner's distance less its longest
  // edge from the centre.
  const double nearest = std::min({skin.distance[corners[0]], skin.distance[corners[1]],
                                   skin.distance[corners[2]]});
  if (nearest - skin.edge[triangle] >= reach) return false;
  const Eigen::Vector3d& c0 = skin.local[corners[0]];
  normal = (skin.local[corners[1]] - c0).cross(skin.local[corners[2]] - c0);
  plane = normal.dot(c0);
  const double length = normal.norm();
  return std::abs(plane) > 1e-12 * length * c0.norm() && std::abs(plane) < reach * length;
}

/// The first and last of the grid lines 0..n of a face side at or after (before) the face
/// coordinate x in [-1, 1] (clamped), within 1e-9 of a line. Grid positions are >= 0 once
/// clamped, so truncation is floor (std::ceil and floor are library calls on the baseline
/// x86-64 this builds for).
int FirstGridLine(double x, int n) {
  const double g = 0.5 * (std::max(x, -1.0) + 1.0) * n - 1e-9;
  const int floor = static_cast<int>(std::max(g, 0.0));
  return floor + (floor < g ? 1 : 0);
}

int LastGridLine(double x, int n) {
  return std::min(n, static_cast<int>(0.5 * (std::min(x, 1.0) + 1.0) * n + 1e-9));
}

/// Calls visit(face, index, lambda) for every map node (a face's grid point `index`) whose
/// ray passes through `triangle`, lambda being the hit in units of the node's point on the
/// box (so the radius is lambda times its distance from the centre); `normal` and `plane`
/// as TriangleWithinReach gives them. The triangle's rays on a face are those of its
/// central projection onto the face's plane, a triangle whose bounding box gives the
/// candidate nodes; a triangle reaching behind the face's plane projects to an unbounded
/// region, which stretches the box to the face's edges. The part of a partly buried
/// triangle inside another piece (SegmentSkin::burial) is clipped off.
template <typename Visit>
void RasterizeTriangle(const SkinDistanceMap& map, int triangle, const SegmentSkin& skin,
                       const Eigen::Vector3d& normal, double plane, Visit&& visit) {
  const Eigen::Vector3i& corners = skin.triangles[triangle];
  const Eigen::Vector3d corner[3] = {skin.local[corners[0]], skin.local[corners[1]],
                                     skin.local[corners[2]]};
  // Inside the triangle's cone of rays: on the inner side of its three edge planes, whose
  // values are also the barycentric weights of the opposite corners (unnormalised). A
  // triangle the centre sees from behind (an entry) winds the other way.
  const double orientation = plane > 0.0 ? 1.0 : -1.0;
  const Eigen::Vector3d edge_planes[3] = {orientation * corner[1].cross(corner[2]),
                                          orientation * corner[2].cross(corner[0]),
                                          orientation * corner[0].cross(corner[1])};
  const std::array<double, 6>* burial =
      skin.partly_buried[triangle] ? &skin.burial[triangle] : nullptr;
  const Eigen::Vector3d p[3] = {skin.scaled[corners[0]], skin.scaled[corners[1]],
                                skin.scaled[corners[2]]};
  // The faces' cones are convex: a triangle whose corners all lie in one lies in it.
  const char* face = skin.face.data();
  const int only = face[corners[0]] == face[corners[1]] && face[corners[0]] == face[corners[2]]
                       ? face[corners[0]] : -1;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int f = only < 0 ? 0 : only; f < (only < 0 ? 6 : only + 1); ++f) {
    const int i = f / 2, j = (i + 1) % 3, k = (i + 2) % 3;
    double s_lo = kInf, s_hi = -kInf, t_lo = kInf, t_hi = -kInf;
    if (only >= 0) {
      // All corners on this face: their in-face coordinates were found once per vertex.
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector2d& st = skin.face_point[corners[c]];
        s_lo = std::min(s_lo, st.x()), s_hi = std::max(s_hi, st.x());
        t_lo = std::min(t_lo, st.y()), t_hi = std::max(t_hi, st.y());
      }
    } else {
      const double sign = f % 2 == 0 ? 1.0 : -1.0;
      const double w[3] = {sign * p[0][i], sign * p[1][i], sign * p[2][i]};
      if (w[0] <= 0.0 && w[1] <= 0.0 && w[2] <= 0.0) continue;
      for (int c = 0; c < 3; ++c) {
        if (w[c] > 0.0) {
          const double s = p[c][j] / w[c], t = p[c][k] / w[c];
          s_lo = std::min(s_lo, s), s_hi = std::max(s_hi, s);
          t_lo = std::min(t_lo, t), t_hi = std::max(t_hi, t);
        }
        const int d = (c + 1) % 3;
        if ((w[c] > 0.0) == (w[d] > 0.0)) continue;
        // The edge crosses the face's plane through the centre: its projection runs off
        // to infinity in the direction of the crossing point's in-face coordinates.
        const double lambda = w[c] / (w[c] - w[d]);
        const Eigen::Vector3d crossing = p[c] + lambda * (p[d] - p[c]);
        if (crossing[j] > 0.0) s_hi = kInf;
        if (crossing[j] < 0.0) s_lo = -kInf;
        if (crossing[k] > 0.0) t_hi = kInf;
        if (crossing[k] < 0.0) t_lo = -kInf;
      }
      if (s_lo > 1.0 || s_hi < -1.0 || t_lo > 1.0 || t_hi < -1.0) continue;
    }
    const int nj = map.intervals[j], nk = map.intervals[k];
    const int u_hi = LastGridLine(s_hi, nj), v_lo = FirstGridLine(t_lo, nk),
              v_hi = LastGridLine(t_hi, nk);
    // The node (u, v)'s ray runs through its point on the box, B = σ·a_i·e_i +
    // a_j·(2u/nj − 1)·e_j + a_k·(2v/nk − 1)·e_k: computed, not loaded. The inside tests
    // hold for B as for the unit ray, and the hit lies at plane / (normal·B) times |B|.
    const Eigen::Vector3d& size = map.size;
    const double sign = f % 2 == 0 ? 1.0 : -1.0;
    Eigen::Vector3d step_u = Eigen::Vector3d::Zero(), step_v = Eigen::Vector3d::Zero();
    step_u[j] = 2.0 * size[j] / nj;
    step_v[k] = 2.0 * size[k] / nk;
    Eigen::Vector3d base = Eigen::Vector3d::Zero();
    base[i] = sign * size[i];
    base[j] = -size[j];
    base[k] = -size[k];
    const double e0v = edge_planes[0].dot(step_v), e1v = edge_planes[1].dot(step_v),
                 e2v = edge_planes[2].dot(step_v), nv = normal.dot(step_v);
    const int u_lo = FirstGridLine(s_lo, nj);
    for (int u = u_lo; u <= u_hi; ++u) {
      const Eigen::Vector3d row = base + u * step_u + v_lo * step_v;
      double b0 = edge_planes[0].dot(row), b1 = edge_planes[1].dot(row),
             b2 = edge_planes[2].dot(row), along = normal.dot(row);
      for (int v = v_lo; v <= v_hi; ++v, b0 += e0v, b1 += e1v, b2 += e2v, along += nv) {
        // Shared edges are tested with opposite signs by their two triangles, so a ray
        // along an edge is taken by both and none falls between.
        if (b0 < 0.0 || b1 < 0.0 || b2 < 0.0) continue;
        if (burial) {
          const double sum = b0 + b1 + b2;
          if (!(sum > 0.0) || InterpolateBurial(*burial, b0 / sum, b1 / sum, b2 / sum) < 0.0) {
            continue;
          }
        }
        visit(f, u * (nk + 1) + v, plane / along);
      }
    }
  }
}

/// Finds, once for the drawing's passes, which triangles can stop a ray within `reach`
/// and their normals and planes (TriangleWithinReach; SegmentSkin::triangle_reached).
void ClassifyTriangles(double reach, SegmentSkin& skin) {
  for (std::size_t tri = 0; tri < skin.triangles.size(); ++tri) {
    skin.triangle_reached[tri] = TriangleWithinReach(reach, static_cast<int>(tri), skin,
                                                     skin.triangle_side[tri],
                                                     skin.triangle_plane[tri]);
  }
}

/// Draws one skin triangle into the map: every node whose ray leaves the skin through it
/// keeps the nearer of its current hit and this one (the ray's first exit).
void DrawTriangle(const SkinDistanceMap& map, int triangle, SegmentSkin& skin) {
  const Eigen::Vector3d& normal = skin.triangle_side[triangle];
  const double plane = skin.triangle_plane[triangle];
  // Rays entering the skin stop nothing here (MarkFoldedRays looks at them).
  if (!skin.triangle_reached[triangle] || plane < 0.0) return;
  skin.triangle_normal[triangle] = normal.normalized();
  RasterizeTriangle(map, triangle, skin, normal, plane, [&](int f, int index, double lambda) {
    double& hit = skin.face_hit[f][index];
    if (hit < 0.0 || lambda < hit) {
      hit = lambda;
      skin.face_triangle[f][index] = triangle;
    }
  });
}

/// Marks the rays that enter skin before their first exit (SegmentSkin::face_hit): that
/// exit leads into skin again, from a fold or from skin that skinning moved through other
/// skin, so it need not be where the ray leaves the body (MakeHuman's kick pushes the
/// thigh's skin through the groin's, and the thigh's centre saw a point 3.6 mm inside the
/// skin 2 mm outside its shell). At most kMaxFoldedRays are marked. Returns whether any.
bool MarkFoldedRays(const SkinDistanceMap& map, SegmentSkin& skin) {
  for (std::size_t tri = 0; tri < skin.triangles.size(); ++tri) {
    const int triangle = static_cast<int>(tri);
    const double plane = skin.triangle_plane[tri];
    if (!skin.triangle_reached[tri] || plane > 0.0) continue;
    RasterizeTriangle(map, triangle, skin, skin.triangle_side[tri], plane,
                      [&](int f, int index, double lambda) {
      const double hit = skin.face_hit[f][index];
      int& slot = skin.face_slot[f][index];
      if (hit < 0.0 || lambda >= hit || slot >= 0 || skin.num_folded == kMaxFoldedRays) return;
      slot = skin.num_folded++;
      skin.folded_ray[slot] = {f, index};
      skin.folded_count[slot] = 0;
    });
  }
  return skin.num_folded > 0;
}

/// The grid box of each face's folded rays (SegmentSkin::folded_box).
void BoxFoldedRays(const SkinDistanceMap& map, SegmentSkin& skin) {
  for (std::array<int, 4>& box : skin.folded_box) box = {1, 0, 1, 0};  // empty
  for (int slot = 0; slot < skin.num_folded; ++slot) {
    const auto [f, index] = skin.folded_ray[slot];
    const int rows = map.intervals[(f / 2 + 2) % 3] + 1;  // a face's points are u-major
    const int u = index / rows, v = index % rows;
    std::array<int, 4>& box = skin.folded_box[f];
    if (box[0] > box[1]) box = {u, u, v, v};
    box = {std::min(box[0], u), std::max(box[1], u), std::min(box[2], v), std::max(box[3], v)};
  }
}

/// Whether `triangle`, its corners all towards one face, projects onto none of that face's
/// folded rays: RasterizeTriangle, which visits the same grid box, would then visit none
/// of them. A triangle over several faces is not decided here (false).
bool MissesFoldedRays(const SkinDistanceMap& map, int triangle, const SegmentSkin& skin) {
  const Eigen::Vector3i& corners = skin.triangles[triangle];
  const int f = skin.face[corners[0]];
  if (skin.face[corners[1]] != f || skin.face[corners[2]] != f) return false;
  const std::array<int, 4>& box = skin.folded_box[f];
  if (box[0] > box[1]) return true;
  const int i = f / 2, nj = map.intervals[(i + 1) % 3], nk = map.intervals[(i + 2) % 3];
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double s_lo = kInf, s_hi = -kInf, t_lo = kInf, t_hi = -kInf;
  for (int c = 0; c < 3; ++c) {
    const Eigen::Vector2d& st = skin.face_point[corners[c]];
    s_lo = std::min(s_lo, st.x()), s_hi = std::max(s_hi, st.x());
    t_lo = std::min(t_lo, st.y()), t_hi = std::max(t_hi, st.y());
  }
  return FirstGridLine(s_lo, nj) > box[1] || LastGridLine(s_hi, nj) < box[0] ||
         FirstGridLine(t_lo, nk) > box[3] || LastGridLine(t_hi, nk) < box[2];
}

/// Moves each folded ray's hit to where it leaves the skin the map holds for good: its
/// crossings with every triangle, in order, wind it in (entry) and out (exit) from 1 at
/// the centre, and the first exit that takes the count to 0 holds. A ray whose count never
/// gets there (its skin's other side is not in the map) or that crosses more than
/// kMaxCrossingsPerRay triangles keeps its first exit.
void ResolveFoldedRays(const SkinDistanceMap& map, SegmentSkin& skin) {
  BoxFoldedRays(map, skin);
  for (std::size_t tri = 0; tri < skin.triangles.size(); ++tri) {
    const int triangle = static_cast<int>(tri);
    if (!skin.triangle_reached[tri] || MissesFoldedRays(map, triangle, skin)) continue;
    const double plane = skin.triangle_plane[tri];
    const int signed_triangle = plane > 0.0 ? triangle + 1 : -(triangle + 1);
    RasterizeTriangle(map, triangle, skin, skin.triangle_side[tri], plane,
                      [&](int f, int index, double lambda) {
      const int slot = skin.face_slot[f][index];
      if (slot < 0) return;
      int& count = skin.folded_count[slot];
      if (count < kMaxCrossingsPerRay) {
        skin.folded_crossing[slot * kMaxCrossingsPerRay + count] = {lambda, signed_triangle};
      }
      ++count;
    });
  }
  for (int slot = 0; slot < skin.num_folded; ++slot) {
    const auto [f, index] = skin.folded_ray[slot];
    skin.face_slot[f][index] = -1;
    const int count = skin.folded_count[slot];
    if (count > kMaxCrossingsPerRay) continue;
    auto* crossing = skin.folded_crossing.data() + slot * kMaxCrossingsPerRay;
    std::sort(crossing, crossing + count);
    int winding = 1;
    for (int c = 0; c < count; ++c) {
      // A ray along an edge meets both triangles sharing it at the same hit: once.
      if (c > 0 && crossing[c].second * crossing[c - 1].second > 0 &&
          crossing[c].first - crossing[c - 1].first <= 1e-9 * crossing[c].first) {
        continue;
      }
      winding += crossing[c].second > 0 ? -1 : 1;
      if (winding > 0) continue;
      if (crossing[c].second > 0 && crossing[c].first > skin.face_hit[f][index]) {
        skin.face_hit[f][index] = crossing[c].first;
        skin.face_triangle[f][index] = crossing[c].second - 1;
        skin.face_folded[f][index] = 1;
      }
      break;
    }
  }
}

/// Gives the nodes no triangle reached (rays leaving through skin that is not in the map:
/// the open ends of a segment's skin) the smallest skin radius of their reached (or already
/// filled) neighbours, ring by ring outwards (breadth first), with the ray as the normal: a
/// cap that never reaches beyond the skin around it, marked capped (no skin seen: triangles
/// beyond the reach are not drawn, so rays running on inside the body end here too).
void FillMissedNodes(const SkinDistanceMap& map, SegmentSkin& skin, double reach) {
  constexpr char kUnknown = 0, kKnown = 1, kQueued = 2;
  std::vector<char>& state = skin.state;
  std::vector<int>& queue = skin.queue;
  queue.clear();
  const int num_nodes = map.num_nodes();
  for (int node = 0; node < num_nodes; ++node) {
    state[node] = skin.hit_radius[node] > 0.0 ? kKnown : kUnknown;
  }
  for (int node = 0; node < num_nodes; ++node) {
    if (state[node] != kUnknown) continue;
    for (int e = map.neighbour_start[node]; e < map.neighbour_start[node + 1]; ++e) {
      if (state[map.neighbours[e]] == kKnown) {
        state[node] = kQueued;
        queue.push_back(node);  // capacity reserved for every node: no allocation
        break;
      }
    }
  }
  if (queue.empty() && num_nodes > 0 && state[0] == kUnknown) {
    // Nothing reached at all: the superquadric itself.
    for (int node = 0; node < num_nodes; ++node) {
      skin.radius[node] = std::min(map.surface_radius[node], reach);
    }
    skin.normal = map.ray;
    std::fill(skin.capped.begin(), skin.capped.end(), 1);
    return;
  }
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const int node = queue[head];
    double smallest = std::numeric_limits<double>::infinity();
    for (int e = map.neighbour_start[node]; e < map.neighbour_start[node + 1]; ++e) {
      const int other = map.neighbours[e];
      if (state[other] == kKnown) {
        smallest = std::min(smallest, skin.radius[other]);
      } else if (state[other] == kUnknown) {
        state[other] = kQueued;
        queue.push_back(other);
      }
    }
    skin.radius[node] = std::min(smallest, reach);
    skin.normal[node] = map.ray[node];
    skin.capped[node] = 1;
    state[node] = kKnown;
  }
}

/// Redraws the map of `segment` from its skin's corners in the superquadric frame
/// (skin.local): rays stop at their first exit from the skin, or at the segment's reach.
/// Then sets the shell's box and bounding radius for `thickness` [m].
void DrawMap(SuperquadricSegment& segment, double thickness) {
  SkinDistanceMap& map = segment.map;
  SegmentSkin& skin = segment.skin;
  for (std::size_t v = 0; v < skin.local.size(); ++v) {
    skin.distance[v] = skin.local[v].norm();
    skin.scaled[v] = skin.local[v].cwiseProduct(segment.inverse_size);
    const Eigen::Vector3d a = skin.scaled[v].cwiseAbs();
    const int i = a.x() >= a.y() ? (a.x() >= a.z() ? 0 : 2) : (a.y() >= a.z() ? 1 : 2);
    skin.face[v] = static_cast<char>(2 * i + (skin.scaled[v][i] < 0.0 ? 1 : 0));
    const double w = a[i];
    skin.face_point[v] = w > 0.0 ? Eigen::Vector2d(skin.scaled[v][(i + 1) % 3] / w,
                                                   skin.scaled[v][(i + 2) % 3] / w)
                                 : Eigen::Vector2d::Zero();
  }
  for (int f = 0; f < 6; ++f) std::fill(skin.face_hit[f].begin(), skin.face_hit[f].end(), -1.0);
  ClassifyTriangles(segment.reach, skin);
  for (std::size_t tri = 0; tri < skin.triangles.size(); ++tri) {
    DrawTriangle(map, static_cast<int>(tri), skin);
  }
  if (MarkFoldedRays(map, skin)) ResolveFoldedRays(map, skin);
  // The faces' grids share their edge nodes: the nearest hit of each holds.
  std::fill(skin.hit_radius.begin(), skin.hit_radius.end(), -1.0);
  for (int f = 0; f < 6; ++f) {
    const std::vector<int>& table = map.face_nodes[f];
    for (std::size_t index = 0; index < table.size(); ++index) {
      if (skin.face_hit[f][index] < 0.0) continue;
      const int node = table[index];
      const double radius = skin.face_hit[f][index] * map.box_length[node];
      if (skin.hit_radius[node] < 0.0 || radius < skin.hit_radius[node]) {
        skin.hit_radius[node] = radius;
        skin.hit_triangle[node] = skin.face_triangle[f][index];
        skin.hit_folded[node] = skin.face_folded[f][index];
      }
    }
  }
  for (int slot = 0; slot < skin.num_folded; ++slot) {
    skin.face_folded[skin.folded_ray[slot].first][skin.folded_ray[slot].second] = 0;
  }
  skin.num_folded = 0;
  for (int node = 0; node < map.num_nodes(); ++node) {
    skin.capped[node] = 0;
    if (skin.hit_radius[node] <= 0.0) continue;
    if (skin.hit_radius[node] >= segment.reach) {
      // The ray runs on inside the body beyond the segment's reach: the shell stops there.
      skin.radius[node] = segment.reach;
      skin.normal[node] = map.ray[node];
      skin.capped[node] = 1;
    } else {
      skin.radius[node] = skin.hit_radius[node];
      skin.normal[node] = skin.triangle_normal[skin.hit_triangle[node]];
      // A folded ray's exit is where the map's skin ends, not always the body's (the other
      // side of a fold may be a neighbour's skin the map lacks): uncertain, as a capped
      // node. A reading deeper than the step's motion allows is then the skin triangles'
      // to decide (SkinShell).
      skin.capped[node] = skin.hit_folded[node];
    }
  }
  FillMissedNodes(map, skin, segment.reach);
  // The shell lies within thickness over the least cosine of the skin points.
  Eigen::AlignedBox3d box(Eigen::Vector3d::Zero());
  double farthest = 0.0;
  for (int node = 0; node < map.num_nodes(); ++node) {
    box.extend(skin.radius[node] * map.ray[node]);
    farthest = std::max(farthest, skin.radius[node]);
  }
  const double shell = thickness / kMinSkinCosine;
  segment.shell_box = Eigen::AlignedBox3d(box.min().array() - shell, box.max().array() + shell);
  segment.bounding_radius = farthest + shell;
}

/// Packs the map of `segment` as just drawn (SegmentSkin's drawing fields) into `nodes`,
/// one per grid point of each face in turn (SkinDistanceMap::face_offset), and points the
/// segment's queries at them.
void PackDrawing(SuperquadricSegment& segment, StoredMapNode* nodes) {
  const SkinDistanceMap& map = segment.map;
  const SegmentSkin& skin = segment.skin;
  StoredMapNode* out = nodes;
  for (int f = 0; f < 6; ++f) {
    for (int node : map.face_nodes[f]) {
      // A radius beyond the steps' range (a reach grown past kRadiusRangePerReach times
      // the rest one) is stored as the largest and capped: the shell there is uncertain,
      // not smaller than the skin. None is 0, which would lose the capped sign.
      const std::int64_t steps = RoundToInteger(skin.radius[node] / segment.radius_step);
      const bool capped = skin.capped[node] || steps > StoredMapNode::kMaxRadiusSteps;
      const std::int64_t stored =
          std::clamp<std::int64_t>(steps, 1, StoredMapNode::kMaxRadiusSteps);
      out->radius = static_cast<std::int16_t>(capped ? -stored : stored);
      for (int a = 0; a < 3; ++a) {
        out->normal[a] = static_cast<std::int16_t>(
            RoundToInteger(skin.normal[node][a] * StoredMapNode::kNormalScale));
      }
      ++out;
    }
  }
  segment.nodes = nodes;
}

/// The record of the drawing `segment` reads, for storing it.
void RecordDrawing(const SuperquadricSegment& segment, StoredMapDrawing& stored) {
  stored.shell_box = segment.shell_box;
  stored.bounding_radius = segment.bounding_radius;
}

/// Points the queries of `segment` at a stored drawing of its current skin.
void UseDrawing(const StoredMapDrawing& stored, const StoredMapNode* nodes,
                SuperquadricSegment& segment) {
  // A stored drawing was last read a whole pass ago and has left the caches: fetched in one
  // sweep here it streams in, where the queries' scattered reads would each wait for memory.
  constexpr int kNodesPerLine = 64 / sizeof(StoredMapNode);
  for (int node = 0; node < stored.num_nodes; node += kNodesPerLine) {
    __builtin_prefetch(nodes + node);
  }
  segment.nodes = nodes;
  segment.shell_box = stored.shell_box;
  segment.bounding_radius = stored.bounding_radius;
}

/// Per H-Anim joint the index of the segment whose map its vertices are drawn into: its
/// own when fitted, else its nearest fitted ancestor's (−1: none).
std::array<int, kNumHAnimJoints> MapOwners(const std::vector<SuperquadricSegment>& segments) {
  std::array<int, kNumHAnimJoints> owner;
  owner.fill(-1);
  for (std::size_t s = 0; s < segments.size(); ++s) {
    owner[static_cast<int>(segments[s].segment)] = static_cast<int>(s);
  }
  for (HAnimJoint joint : AllHAnimJoints()) {  // parents first
    const std::optional<HAnimJoint> parent = HAnimParent(joint);
    int& own = owner[static_cast<int>(joint)];
    if (own < 0 && parent) own = owner[static_cast<int>(*parent)];
  }
  return owner;
}

/// A point of the skin more than this deep inside another closed piece of the body [m] is
/// not skin. Not zero: where two pieces meet along a shared surface (the pelvis's top on
/// the torso's bottom), their facets cross each other by about their chord sag (1 mm for
/// 3 cm facets on a 10 cm radius), and both must stay.
constexpr double kBuriedDepth = 0.0015;

/// Per triangle, in the rest pose, the signed distance [m] of its corners and edge midpoints
/// (0, 1, 2, then the midpoints of edges 12, 20, 01) from the body's other closed pieces,
/// plus kBuriedDepth (< 0: buried; +inf: no other piece within reach). A body made of
/// overlapping closed pieces, as the built-in humanoid, has surfaces inside other pieces
/// where they meet; a ray from a segment's centre must not stop at them. All +inf for a
/// body of one piece or a mesh that is not closed (inside is undefined).
std::vector<std::array<double, 6>> Burial(const Avatar& avatar) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const auto& triangles = avatar.triangles();
  std::vector<std::array<double, 6>> burial(triangles.size());
  for (auto& b : burial) b.fill(kInf);
  const SurfacePseudonormals topology(avatar.num_vertices(), triangles);
  if (topology.num_pieces() <= 1 || topology.num_open_edges() > 0) return burial;
  std::vector<std::vector<Eigen::Vector3i>> pieces(topology.num_pieces());
  for (int t = 0; t < topology.num_triangles(); ++t) {
    pieces[topology.piece_of(t)].push_back(triangles[t]);
  }
  const Points& rest = avatar.rest_vertices();
  const auto sample = [&](const Eigen::Vector3i& tri, int k) -> Eigen::Vector3d {
    if (k < 3) return rest.row(tri[k]).transpose();
    return 0.5 * (rest.row(tri[(k - 2) % 3]) + rest.row(tri[k % 3])).transpose();
  };
  constexpr double kReach = 0.5;  // deeper than any part of a body is thick
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3i& tri : pieces[p]) {
      for (int c = 0; c < 3; ++c) box.extend(Eigen::Vector3d(rest.row(tri[c]).transpose()));
    }
    const MeshDistance distance("piece " + std::to_string(p), rest, pieces[p]);
    for (std::size_t t = 0; t < triangles.size(); ++t) {
      if (topology.piece_of(static_cast<int>(t)) == static_cast<int>(p)) continue;
      for (int k = 0; k < 6; ++k) {
        const Eigen::Vector3d x = sample(triangles[t], k);
        if (box.exteriorDistance(x) > 0.0) continue;  // outside the piece's box
        burial[t][k] = std::min(burial[t][k], distance.SignedDistance(x, kReach) + kBuriedDepth);
      }
    }
  }
  return burial;
}

/// Per segment its nearest fitted H-Anim ancestor's index (−1: none; the pelvis and the
/// torso under an unfitted root).
std::vector<int> FittedParents(const std::vector<SuperquadricSegment>& segments) {
  std::array<int, kNumHAnimJoints> index;
  index.fill(-1);
  for (std::size_t s = 0; s < segments.size(); ++s) {
    index[static_cast<int>(segments[s].segment)] = static_cast<int>(s);
  }
  std::vector<int> parents(segments.size(), -1);
  for (std::size_t s = 0; s < segments.size(); ++s) {
    for (std::optional<HAnimJoint> up = HAnimParent(segments[s].segment); up;
         up = HAnimParent(*up)) {
      if (index[static_cast<int>(*up)] >= 0) {
        parents[s] = index[static_cast<int>(*up)];
        break;
      }
    }
  }
  return parents;
}

/// Per segment, the segments next to it in the H-Anim hierarchy as far as it is fitted: the
/// nearest fitted ancestor, the segments whose nearest fitted ancestor it is, and, for
/// segments without a fitted ancestor (the pelvis and the torso under an unfitted root),
/// each other.
std::vector<std::vector<int>> Neighbours(const std::vector<SuperquadricSegment>& segments) {
  const std::vector<int> parents = FittedParents(segments);
  std::vector<std::vector<int>> neighbours(segments.size());
  for (std::size_t s = 0; s < segments.size(); ++s) {
    const int up = parents[s];
    for (std::size_t o = 0; o < segments.size(); ++o) {
      if (o == s) continue;
      const int other_up = parents[o];
      const bool parent = static_cast<int>(o) == up, child = other_up == static_cast<int>(s);
      if (parent || child || (up < 0 && other_up < 0)) {
        neighbours[s].push_back(static_cast<int>(o));
      }
    }
  }
  return neighbours;
}

/// A segment's centre sees a triangle's outside well enough to hold it when the cosine
/// between the triangle's normal and the ray to it reaches this [-].
constexpr double kViewerCosine = 0.3;

/// Appends the avatar triangle `tri` (with its burial `b`) to `skin`, numbering corners the
/// skin has not seen yet through `local` (avatar vertex -> skin vertex, -1: not yet).
void AddSkinTriangle(const Eigen::Vector3i& tri, const std::array<double, 6>& b,
                     std::vector<int>& local, SegmentSkin& skin) {
  Eigen::Vector3i corners;
  for (int m = 0; m < 3; ++m) {
    int& index = local[tri[m]];
    if (index < 0) {
      index = static_cast<int>(skin.vertices.size());
      skin.vertices.push_back(tri[m]);
    }
    corners[m] = index;
  }
  skin.triangles.push_back(corners);
  skin.burial.push_back(b);
  skin.partly_buried.push_back(*std::min_element(b.begin(), b.end()) < 0.0 ? 1 : 0);
}

/// Gives every skin triangle to the maps of the segments of its corners and of their
/// neighbours (Neighbours). A map's ray stops where it first leaves the skin, so a
/// segment's map must hold the skin around it, not only its own: the skinning weights
/// alone give the underside of the pelvis to the thighs, whose centres below see it from
/// inside. Triangles wholly inside other pieces of the body (by their burial samples) are
/// left out.
void AssignSkin(const Avatar& avatar, const std::vector<std::array<double, 6>>& burial,
                std::vector<SuperquadricSegment>& segments) {
  const std::array<int, kNumHAnimJoints> owner = MapOwners(segments);
  const std::vector<std::vector<int>> neighbours = Neighbours(segments);
  const auto& of = avatar.vertex_segments();
  std::vector<std::vector<int>> local(segments.size());
  std::vector<char> chosen(segments.size(), 0);
  const Points& rest = avatar.rest_vertices();
  std::vector<Eigen::Vector3d> centres;
  for (const SuperquadricSegment& segment : segments) {
    centres.push_back(avatar.skeleton().rest_world()[segment.joint] *
                      segment.superquadric.frame.translation());
  }
  for (std::size_t t = 0; t < avatar.triangles().size(); ++t) {
    const Eigen::Vector3i& tri = avatar.triangles()[t];
    const std::array<double, 6>& b = burial[t];
    if (*std::max_element(b.begin(), b.end()) < 0.0) continue;
    std::fill(chosen.begin(), chosen.end(), 0);
    for (int c = 0; c < 3; ++c) {
      const int mine = of[tri[c]] ? owner[static_cast<int>(*of[tri[c]])] : -1;
      if (mine < 0) continue;
      chosen[mine] = 1;
      for (int n : neighbours[mine]) chosen[n] = 1;
    }
    // The nearest centre that sees the triangle's outside (else the one that sees it most
    // squarely) is the one whose shell is to hold it: its reach must get there.
    const Eigen::Vector3d a = rest.row(tri[0]), bv = rest.row(tri[1]), c = rest.row(tri[2]);
    const Eigen::Vector3d normal = (bv - a).cross(c - a).normalized();
    const Eigen::Vector3d centroid = (a + bv + c) / 3.0;
    int viewer = -1, squarest = -1;
    double nearest = std::numeric_limits<double>::infinity(), best = -2.0;
    for (std::size_t s = 0; s < segments.size(); ++s) {
      if (!chosen[s]) continue;
      const Eigen::Vector3d ray = centroid - centres[s];
      const double cosine = normal.dot(ray.normalized());
      if (cosine > best) best = cosine, squarest = static_cast<int>(s);
      if (cosine >= kViewerCosine && ray.norm() < nearest) {
        nearest = ray.norm(), viewer = static_cast<int>(s);
      }
    }
    if (viewer < 0) viewer = squarest;
    if (viewer >= 0) {
      for (int k = 0; k < 3; ++k) segments[viewer].viewed.push_back(tri[k]);
    }
    for (std::size_t s = 0; s < segments.size(); ++s) {
      if (!chosen[s]) continue;
      if (local[s].empty()) local[s].assign(avatar.num_vertices(), -1);
      AddSkinTriangle(tri, b, local[s], segments[s].skin);
    }
  }
}

/// How far beyond a segment's rest reach a triangle may lie and still be drawn into its
/// map [m]: bending a joint carries skin farther out by this much at most.
constexpr double kReachSlack = 0.1;

/// Bound on how much skinning lengthens a triangle's edges [-].
constexpr double kEdgeStretch = 1.5;

/// How far beyond its own skin's farthest rest vertex a segment's shell may reach [m]:
/// beyond, the neighbours' shells hold the skin, and a thigh's shell need not follow its
/// rays down the calf.
constexpr double kReachMargin = 0.06;

/// A map's stored radii (StoredMapNode) run up to this many times its rest reach: a pose
/// moves a segment's farthest skin from its centre by centimetres (a bent knee's front),
/// not by the reach again (10–30 µm steps for reaches of 15–50 cm; PackDrawing caps a
/// radius beyond).
constexpr double kRadiusRangePerReach = 2.0;

/// A map's rays start at its centre and stop where they first leave the skin: a centre must
/// lie this far inside the skin [m], or its first exits can bound air.
constexpr double kMinCentreDepth = 0.005;

/// The rest skin's signed distance field, for a body whose mesh is closed and consistently
/// oriented (null otherwise: inside is undefined).
std::unique_ptr<MeshDistance> RestSkin(const Avatar& avatar) {
  const SurfacePseudonormals topology(avatar.num_vertices(), avatar.triangles());
  if (topology.num_open_edges() > 0) return nullptr;
  return std::make_unique<MeshDistance>("avatar '" + avatar.name() + "'",
                                        avatar.rest_vertices(), avatar.triangles());
}

/// Moves each superquadric whose centre lies less than kMinCentreDepth inside the rest skin
/// to the point, among points sampled on its three axes within its sizes and its joint, that
/// is nearest its fitted centre and at least that deep (failing any, the deepest): a fit's
/// centre is the middle of its vertices, which for a hand with curled fingers lies outside
/// (MakeHuman: 2 mm), and the first exits of rays starting outside bound air (hand shells up
/// to 6 cm out). Records the move in `centre_shift`.
void CentreInsideSkin(const Avatar& avatar, const MeshDistance& skin,
                      std::vector<SuperquadricSegment>& segments) {
  constexpr int kSamples = 16;  // intervals per axis
  constexpr double kSearch = 0.5;
  for (SuperquadricSegment& segment : segments) {
    const Eigen::Isometry3d& joint = avatar.skeleton().rest_world()[segment.joint];
    Superquadric& sq = segment.superquadric;
    const Eigen::Vector3d fitted = sq.frame.translation();
    if (skin.SignedDistance(joint * fitted, kSearch) <= -kMinCentreDepth) continue;
    std::vector<Eigen::Vector3d> candidates{Eigen::Vector3d::Zero()};  // the joint
    const double size[3] = {sq.a1, sq.a2, sq.a3};
    for (int axis = 0; axis < 3; ++axis) {
      for (int k = 0; k <= kSamples; ++k) {
        const double t = -1.0 + 2.0 * k / kSamples;
        candidates.push_back(fitted + t * size[axis] * sq.frame.linear().col(axis));
      }
    }
    Eigen::Vector3d nearest = fitted, deepest = fitted;
    double nearest_distance = std::numeric_limits<double>::infinity();
    double deepest_depth = -skin.SignedDistance(joint * fitted, kSearch);
    for (const Eigen::Vector3d& c : candidates) {
      const double depth = -skin.SignedDistance(joint * c, kSearch);
      if (depth > deepest_depth) deepest_depth = depth, deepest = c;
      if (depth >= kMinCentreDepth && (c - fitted).norm() < nearest_distance) {
        nearest_distance = (c - fitted).norm(), nearest = c;
      }
    }
    sq.frame.translation() = std::isfinite(nearest_distance) ? nearest : deepest;
    segment.centre_shift = (sq.frame.translation() - fitted).norm();
  }
}

/// A joint shell holds the skin within this many times the child segment's girth (the
/// middle of its superquadric's half sizes) of the joint [-].
constexpr double kJointHoldFactor = 1.5;

/// Appends a joint shell per fitted segment with a fitted parent: a sphere centred on the
/// segment's joint, in the joint's frame, whose map holds the skin of the segment, its parent
/// and their neighbours near the joint, and whose rays start at the joint. The joint lies
/// inside the skin at the bend, so its rays see the bottom of the crease a bent joint folds
/// (the back of a bent knee), which neither segment's centre sees. The held skin is that of
/// the two segments within kJointHoldFactor girths of the joint.
void AddJointShells(const Avatar& avatar, const std::vector<std::array<double, 6>>& burial,
                    const MeshDistance* rest_skin, std::vector<SuperquadricSegment>& segments) {
  const std::size_t fitted = segments.size();
  const std::vector<int> parents = FittedParents(segments);
  const std::vector<std::vector<int>> neighbours = Neighbours(segments);
  const std::array<int, kNumHAnimJoints> owner = MapOwners(segments);
  const auto& of = avatar.vertex_segments();
  const Points& rest = avatar.rest_vertices();
  std::vector<char> allowed(fitted, 0);
  for (std::size_t s = 0; s < fitted; ++s) {
    const int p = parents[s];
    if (p < 0) continue;
    const Superquadric& child = segments[s].superquadric;
    std::array<double, 3> sizes{child.a1, child.a2, child.a3};
    std::sort(sizes.begin(), sizes.end());
    const double hold = kJointHoldFactor * sizes[1];
    const Eigen::Vector3d centre = avatar.skeleton().rest_world()[segments[s].joint].translation();
    // Rays from a joint outside the skin would bound air.
    if (rest_skin && rest_skin->SignedDistance(centre, 0.5) > -kMinCentreDepth) continue;
    std::fill(allowed.begin(), allowed.end(), 0);
    for (int k : {static_cast<int>(s), p}) {
      allowed[k] = 1;
      for (int n : neighbours[k]) allowed[n] = 1;
    }
    const auto owned_by = [&](int v) {
      return of[v] ? owner[static_cast<int>(*of[v])] : -1;
    };
    SuperquadricSegment shell;
    shell.segment = segments[s].segment;
    shell.joint = segments[s].joint;
    shell.joint_shell = true;
    shell.superquadric.a1 = shell.superquadric.a2 = shell.superquadric.a3 = sizes[1];
    shell.inverse_size = Eigen::Vector3d::Constant(1.0 / sizes[1]);
    for (int v = 0; v < avatar.num_vertices(); ++v) {
      const int o = owned_by(v);
      if ((o == static_cast<int>(s) || o == p) &&
          (rest.row(v).transpose() - centre).norm() <= hold) {
        shell.viewed.push_back(v);
      }
    }
    if (shell.viewed.empty()) continue;
    shell.num_vertices = static_cast<int>(shell.viewed.size());
    // The skin near the joint (PrepareMap trims it to the reach).
    const double keep = hold + kReachMargin + kReachSlack;
    std::vector<int> local(avatar.num_vertices(), -1);
    SegmentSkin& skin = shell.skin;
    for (std::size_t t = 0; t < avatar.triangles().size(); ++t) {
      const Eigen::Vector3i& tri = avatar.triangles()[t];
      const std::array<double, 6>& b = burial[t];
      if (*std::max_element(b.begin(), b.end()) < 0.0) continue;
      bool mine = false;
      double nearest = std::numeric_limits<double>::infinity();
      for (int c = 0; c < 3; ++c) {
        const int o = owned_by(tri[c]);
        mine = mine || (o >= 0 && allowed[o]);
        nearest = std::min(nearest, (rest.row(tri[c]).transpose() - centre).norm());
      }
      if (!mine || nearest > keep) continue;
      AddSkinTriangle(tri, b, local, skin);
    }
    segments.push_back(std::move(shell));
  }
}

/// Keeps only the skin triangles that come within `keep` [m] of the segment's centre in the
/// rest pose (`to_local`: world to the superquadric's frame).
void DropFarTriangles(const Avatar& avatar, const Eigen::Isometry3d& to_local, double keep,
                      SegmentSkin& skin) {
  std::vector<Eigen::Vector3i> triangles;
  std::vector<std::array<double, 6>> burial;
  std::vector<char> partly;
  for (std::size_t t = 0; t < skin.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = skin.triangles[t];
    Eigen::Vector3d c[3];
    double longest = 0.0, nearest = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) {
      c[k] = to_local * avatar.rest_vertices().row(skin.vertices[tri[k]]).transpose();
      nearest = std::min(nearest, c[k].norm());
    }
    for (int k = 0; k < 3; ++k) longest = std::max(longest, (c[k] - c[(k + 1) % 3]).norm());
    if (nearest - longest > keep) continue;
    triangles.push_back(tri);
    burial.push_back(skin.burial[t]);
    partly.push_back(skin.partly_buried[t]);
  }
  skin.triangles.swap(triangles);
  skin.burial.swap(burial);
  skin.partly_buried.swap(partly);
}

/// The longest each skin triangle's edges may grow under skinning [m], from the rest pose.
void MeasureEdges(const Avatar& avatar, SegmentSkin& skin) {
  skin.edge.resize(skin.triangles.size());
  for (std::size_t t = 0; t < skin.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = skin.triangles[t];
    double longest = 0.0;
    for (int c = 0; c < 3; ++c) {
      longest = std::max(longest, (avatar.rest_vertices().row(skin.vertices[tri[c]]) -
                                   avatar.rest_vertices().row(skin.vertices[tri[(c + 1) % 3]]))
                                      .norm());
    }
    // Skinning stretches the skin a little: a margin on the rest length.
    skin.edge[t] = kEdgeStretch * longest;
    skin.longest_edge = std::max(skin.longest_edge, skin.edge[t]);
  }
}

/// Allocates the scratch a drawing of the segment's map works in, once, so that drawing
/// never allocates.
void AllocateDrawingScratch(SuperquadricSegment& segment) {
  SegmentSkin& skin = segment.skin;
  const int nodes = segment.map.num_nodes();
  skin.local.assign(skin.vertices.size(), Eigen::Vector3d::Zero());
  skin.scaled.assign(skin.vertices.size(), Eigen::Vector3d::Zero());
  skin.face.assign(skin.vertices.size(), 0);
  skin.face_point.assign(skin.vertices.size(), Eigen::Vector2d::Zero());
  skin.triangle_normal.assign(skin.triangles.size(), Eigen::Vector3d::UnitZ());
  skin.triangle_reached.assign(skin.triangles.size(), 0);
  skin.triangle_side.assign(skin.triangles.size(), Eigen::Vector3d::Zero());
  skin.triangle_plane.assign(skin.triangles.size(), 0.0);
  skin.distance.assign(skin.vertices.size(), 0.0);
  skin.hit_radius.assign(nodes, -1.0);
  skin.hit_triangle.assign(nodes, -1);
  skin.hit_folded.assign(nodes, 0);
  for (int f = 0; f < 6; ++f) {
    skin.face_hit[f].assign(segment.map.face_nodes[f].size(), -1.0);
    skin.face_triangle[f].assign(segment.map.face_nodes[f].size(), -1);
    skin.face_slot[f].assign(segment.map.face_nodes[f].size(), -1);
    skin.face_folded[f].assign(segment.map.face_nodes[f].size(), 0);
  }
  skin.folded_ray.assign(kMaxFoldedRays, {0, 0});
  skin.folded_count.assign(kMaxFoldedRays, 0);
  skin.folded_crossing.assign(static_cast<std::size_t>(kMaxFoldedRays) * kMaxCrossingsPerRay,
                              {0.0, 0});
  skin.num_folded = 0;
  skin.state.assign(nodes, 0);
  skin.queue.reserve(nodes);
  skin.radius = segment.map.surface_radius;
  skin.normal = segment.map.ray;
  skin.capped.assign(nodes, 0);
  segment.own_nodes.resize(segment.map.num_face_points);
  skin.topology.emplace(static_cast<int>(skin.vertices.size()), skin.triangles);
  skin.corners.resize(static_cast<Eigen::Index>(skin.vertices.size()), 3);
  skin.piece_distance.resize(skin.topology->num_pieces());
  skin.piece_triangle.resize(skin.topology->num_pieces());
  skin.piece_point.resize(skin.topology->num_pieces());
  skin.ray_crossing.reserve(skin.triangles.size());
}

/// Sizes a segment's map and scratch: the grid spans the box of the skin it holds (its own
/// vertices, `own`, and the triangles it sees most squarely, segment.viewed) in the
/// superquadric's frame, and the shell reaches that skin's farthest vertex plus
/// kReachMargin (in the rest pose here; MoveSkin follows the pose).
void PrepareMap(const Avatar& avatar, const std::vector<int>& own, double map_spacing,
                SuperquadricSegment& segment) {
  const Eigen::Isometry3d to_local =
      (avatar.skeleton().rest_world()[segment.joint] * segment.superquadric.frame).inverse();
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();
  double farthest = 0.0;
  std::vector<int> held = own;
  held.insert(held.end(), segment.viewed.begin(), segment.viewed.end());
  segment.viewed.clear();
  segment.viewed.shrink_to_fit();
  SegmentSkin& skin = segment.skin;
  std::vector<int> local(avatar.num_vertices(), -1);
  for (std::size_t k = 0; k < skin.vertices.size(); ++k) {
    local[skin.vertices[k]] = static_cast<int>(k);
  }
  for (int v : held) {
    const Eigen::Vector3d q = to_local * avatar.rest_vertices().row(v).transpose();
    extent = extent.cwiseMax(q.cwiseAbs());
    farthest = std::max(farthest, q.norm());
    if (local[v] >= 0) skin.held.push_back(local[v]);
  }
  std::sort(skin.held.begin(), skin.held.end());
  skin.held.erase(std::unique(skin.held.begin(), skin.held.end()), skin.held.end());
  segment.map = MakeMapGrid(segment.superquadric, extent, map_spacing);
  segment.reach = farthest + kReachMargin;
  segment.radius_step = kRadiusRangePerReach * segment.reach / StoredMapNode::kMaxRadiusSteps;
  // Triangles that lie well beyond the reach in the rest pose never stop a ray short of it
  // (bending a joint moves skin by centimetres, not decimetres): they are not drawn.
  DropFarTriangles(avatar, to_local, segment.reach + kReachSlack, skin);
  MeasureEdges(avatar, skin);
  AllocateDrawingScratch(segment);
}

SuperquadricSegment MakeSegment(const SegmentSuperquadricFit& fit) {
  SuperquadricSegment segment;
  segment.segment = fit.segment;
  segment.joint = fit.joint;
  segment.superquadric = fit.fit.superquadric;
  segment.fit_rms = fit.fit.rms_radial_distance;
  segment.num_vertices = fit.num_vertices;
  const Superquadric& sq = segment.superquadric;
  segment.inverse_size = Eigen::Vector3d(1.0 / sq.a1, 1.0 / sq.a2, 1.0 / sq.a3);
  return segment;
}

/// Position-correction passes per particle in ProjectOut.
constexpr int kProjectionPasses = 8;

/// A particle less than this inside a shell is left where it is by ProjectOut [m]. A push
/// along the superquadric's gradient, which is not the skin's normal, leaves a remainder
/// inside that shrinks each pass: without it, a tenth of a skirt's particles went through
/// all the passes for pushes below 0.1 µm, and ProjectOut searched twice as often as
/// FindContacts (docs/collision.md, "Figures").
constexpr double kProjectionTolerance = 1e-6;

/// How far from the skin SkinShell searches [m]: a point farther from every triangle of
/// the segment's skin (deeper than a limb is thick) is left undecided.
constexpr double kSkinCheckRadius = 0.1;

}  // namespace

std::vector<SegmentSuperquadricFit> FitAvatarSegments(const Avatar& avatar,
                                                      const SuperquadricColliderOptions& options) {
  ValidateOptions(options, "superquadric fit of avatar '" + avatar.name() + "'");
  return FitGroups(avatar, GroupVertices(avatar), options);
}

void ProbeShell(const SuperquadricSegment& segment, const Eigen::Vector3d& q, double thickness,
                ShellProbe& probe) {
  const double length = q.norm();
  probe.direction = length > 0.0 ? Eigen::Vector3d(q / length) : Eigen::Vector3d::UnitZ();
  double radius = 0.0;
  Eigen::Vector3d skin_normal;
  LookUp(segment, probe.direction, radius, skin_normal, probe.capped, probe.blind);
  const double norm = skin_normal.norm();
  probe.skin_normal = norm > 0.0 ? Eigen::Vector3d(skin_normal / norm) : probe.direction;
  probe.cosine = std::max(probe.direction.dot(probe.skin_normal), kMinSkinCosine);
  probe.shell_radius = radius + thickness / probe.cosine;
  probe.radial_gap = length - probe.shell_radius;
  probe.normal_gap = probe.radial_gap * probe.cosine;
}

// ---- the collider ---------------------------------------------------------------------------

SuperquadricCollider::SuperquadricCollider(std::shared_ptr<const Avatar> avatar,
                                           const BodyCollisionSettings& settings,
                                           const SuperquadricColliderOptions& options)
    : avatar_(std::move(avatar)),
      settings_(settings),
      skin_normals_(options.contact_normal == SuperquadricColliderOptions::ContactNormal::kSkin) {
  if (!avatar_) throw InputError("superquadric collider: no avatar");
  const std::string where = "superquadric collider of avatar '" + avatar_->name() + "'";
  RequireNonNegative(where + ": thickness", settings.thickness, "m");
  RequireNonNegative(where + ": friction", settings.friction, "");
  ValidateOptions(options, where);
  map_cache_ = SkinMapCache(options.map_cache_bytes, options.map_cache_quantum);
  for (const SegmentSuperquadricFit& fit : FitGroups(*avatar_, GroupVertices(*avatar_), options)) {
    if (fit.fitted) {
      segments_.push_back(MakeSegment(fit));
    } else {
      skipped_.push_back(fit.segment);
    }
  }
  const std::unique_ptr<MeshDistance> rest_skin = RestSkin(*avatar_);
  if (rest_skin) CentreInsideSkin(*avatar_, *rest_skin, segments_);
  const std::vector<std::array<double, 6>> burial = Burial(*avatar_);
  AssignSkin(*avatar_, burial, segments_);
  AddJointShells(*avatar_, burial, rest_skin.get(), segments_);
  const SegmentGroups groups = GroupVertices(*avatar_);
  for (SuperquadricSegment& segment : segments_) {
    // A joint shell holds the skin listed in `viewed`, none of its own.
    const std::vector<int> none;
    PrepareMap(*avatar_,
               segment.joint_shell ? none : groups[static_cast<int>(segment.segment)],
               options.map_spacing, segment);
  }
  const std::size_t n = segments_.size();
  start_.resize(n);
  end_.resize(n);
  stale_.assign(n, 0);
  motion_.assign(n, Eigen::Isometry3d::Identity());
  sweep_.assign(n, 0.0);
  active_.reserve(n);
  active_centre_.resize(n);
  active_bound_.resize(n);
  SetPose(avatar_->skeleton().rest_world(), end_);
  start_ = end_;
  MoveSkin(avatar_->rest_vertices());
  RefreshAllMaps();
}

void SuperquadricCollider::SetPose(const std::vector<Eigen::Isometry3d>& joint_world,
                                   std::vector<Placement>& out) {
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    out[s].to_world = joint_world[segments_[s].joint] * segments_[s].superquadric.frame;
    out[s].to_local = out[s].to_world.inverse(Eigen::Isometry);
  }
}

void SuperquadricCollider::MoveSkin(const Points& skinned) {
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    SuperquadricSegment& segment = segments_[s];
    SegmentSkin& skin = segment.skin;
    const Eigen::Isometry3d& to_local = end_[s].to_local;
    for (std::size_t k = 0; k < skin.vertices.size(); ++k) {
      skin.local[k] = to_local * skinned.row(skin.vertices[k]).transpose();
    }
    // The reach follows the skin the segment holds: bending a knee carries the skin at its
    // front away from both the thigh's and the calf's centres.
    double farthest = 0.0;
    for (int k : skin.held) farthest = std::max(farthest, skin.local[k].squaredNorm());
    segment.reach = std::sqrt(farthest) + kReachMargin;
    skin.corners_current = false;
    // Until the map is redrawn, the shell is known to lie within the reach and within the
    // box of the skin the rays can stop at (corners within the reach and an edge), grown by
    // the thickness term and a node spacing for the caps filled at open ends.
    const double grow = settings_.thickness / kMinSkinCosine + segment.map.spacing;
    const double near = segment.reach + skin.longest_edge;
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3d& q : skin.local) {
      if (q.squaredNorm() <= near * near) box.extend(q);
    }
    const Eigen::Vector3d cube = Eigen::Vector3d::Constant(segment.reach);
    segment.shell_box =
        box.isEmpty() ? Eigen::AlignedBox3d(-cube, cube)
                      : Eigen::AlignedBox3d(box.min().cwiseMax(-cube), box.max().cwiseMin(cube));
    segment.shell_box.min().array() -= grow;
    segment.shell_box.max().array() += grow;
    segment.bounding_radius = segment.reach + grow;
    stale_[s] = 1;
  }
}

void SuperquadricCollider::RefreshMap(int s) {
  SuperquadricSegment& segment = segments_[s];
  stale_[s] = 0;
  const std::uint64_t key = map_cache_.enabled() ? map_cache_.Key(s, segment.skin.local) : 0;
  if (const StoredMapDrawing* stored = map_cache_.Find(key)) {
    UseDrawing(*stored, map_cache_.Nodes(*stored), segment);
    ++stats_.num_maps_reused;
    return;
  }
  DrawMap(segment, settings_.thickness);
  ++stats_.num_maps_drawn;
  StoredMapNode* nodes = nullptr;
  StoredMapDrawing* stored = map_cache_.Reserve(key, segment.map.num_face_points, nodes);
  PackDrawing(segment, stored ? nodes : segment.own_nodes.data());
  if (stored) RecordDrawing(segment, *stored);
}

void SuperquadricCollider::RefreshAllMaps() {
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    if (stale_[s]) RefreshMap(static_cast<int>(s));
  }
}

void SuperquadricCollider::Update(const std::vector<Eigen::Isometry3d>& joint_world,
                                  const Points& skinned_vertices, double dt) {
  const bool usable =
      joint_world.size() >= static_cast<std::size_t>(avatar_->skeleton().num_joints());
  if (usable) {
    start_ = end_;  // same size: no allocation
    SetPose(joint_world, end_);
    if (skinned_vertices.rows() == avatar_->num_vertices()) MoveSkin(skinned_vertices);
  }
  const bool moving = usable && has_pose_ && std::isfinite(dt) && dt > 0.0;
  if (usable) has_pose_ = true;
  if (!moving) start_ = end_;
  inverse_dt_ = moving ? 1.0 / dt : 0.0;
  step_ = moving ? dt : 0.0;
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    motion_[s] = end_[s].to_world * start_[s].to_local;
    const double angle = Eigen::AngleAxisd(motion_[s].linear()).angle();
    // The largest shell the segment can have, as its map may not be drawn yet.
    const double radius = segments_[s].reach + settings_.thickness / kMinSkinCosine;
    sweep_[s] = (end_[s].to_world.translation() - start_[s].to_world.translation()).norm() +
                radius * std::abs(angle);
  }
}

double SuperquadricCollider::PlausibleDepth(int segment, const Eigen::Vector3d& x,
                                            bool at_end) const {
  // The body's motion, not the particle's: cloth sliding fast along the skin comes no
  // deeper for it, and on MakeHuman's suit the collar sliding down the chest at 2 m/s had
  // the upper arm's map, whose rays pass through the armpit into the torso, read it 41 mm
  // deep; trusted for its speed, the reading threw it 43 mm along the chest (202 % strain).
  // Cloth driven in deeper than this is for the skin triangles (ProjectOut).
  return settings_.thickness + segments_[segment].map.spacing +
         step_ * BodyVelocity(segment, x, at_end).norm();
}

Eigen::Vector3d SuperquadricCollider::BodyVelocity(int segment, const Eigen::Vector3d& x,
                                                   bool at_end) const {
  if (inverse_dt_ == 0.0) return Eigen::Vector3d::Zero();
  const Eigen::Isometry3d& motion = motion_[segment];
  if (!at_end) return (motion * x - x) * inverse_dt_;
  return (x - motion.inverse(Eigen::Isometry) * x) * inverse_dt_;
}

double SuperquadricCollider::Motion(int segment, bool at_end) const {
  // FindContacts looks ahead over the step, where a swinging limb may reach cloth outside
  // its shell now; ProjectOut tests the body where the step ends, so it is not grown (that
  // took a ninth of its probes on the built-in walk; docs/collision.md).
  return at_end ? 0.0 : sweep_[segment];
}

void SuperquadricCollider::CullSegments(bool at_end, const Eigen::Vector3d& lo,
                                        const Eigen::Vector3d& hi, double reach) {
  const std::vector<Placement>& placements = at_end ? end_ : start_;
  active_.clear();
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    const Eigen::Vector3d centre = placements[s].to_world.translation();
    const Eigen::Vector3d nearest = centre.cwiseMax(lo).cwiseMin(hi);
    const double shell = segments_[s].bounding_radius + Motion(static_cast<int>(s), at_end);
    const double bound = shell + reach;
    if ((centre - nearest).squaredNorm() > bound * bound) continue;
    active_.push_back(static_cast<int>(s));
    active_centre_[active_.size() - 1] = centre;
    active_bound_[active_.size() - 1] = shell;
  }
}

namespace {

void BoundingBox(const Points& positions, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  lo = positions.colwise().minCoeff().transpose();
  hi = positions.colwise().maxCoeff().transpose();
}

}  // namespace

bool SuperquadricCollider::DeepestShell(const Eigen::Vector3d& x, bool at_end, double reach,
                                        double& gap, Eigen::Vector3d& normal,
                                        Eigen::Vector3d& body_velocity,
                                        Undecided* undecided) {
  const std::vector<Placement>& placement = at_end ? end_ : start_;
  gap = std::numeric_limits<double>::infinity();
  int deepest = -1;
  if (undecided) undecided->count = 0;
  ShellProbe best;
  stats_.num_tests += static_cast<long long>(active_.size());
  for (std::size_t a = 0; a < active_.size(); ++a) {
    // The active segments' centres and bounds sit in two small arrays: most particles are
    // far from most segments, and this test is all they cost.
    const double bound = active_bound_[a] + reach;
    if ((x - active_centre_[a]).squaredNorm() > bound * bound) continue;
    const int s = active_[a];
    const SuperquadricSegment& segment = segments_[s];
    const double grow = reach + Motion(s, at_end);
    const Eigen::Vector3d q = placement[s].to_local * x;
    const auto outside = [&] {
      return (q.array() < segment.shell_box.min().array() - grow).any() ||
             (q.array() > segment.shell_box.max().array() + grow).any();
    };
    if (outside()) continue;
    if (stale_[s]) {
      // The first particle near a segment since the last Update redraws its map, which
      // tightens its box.
      RefreshMap(s);
      active_bound_[a] = segment.bounding_radius + Motion(s, at_end);
      if (outside()) continue;
    }
    ShellProbe probe;
    ProbeShell(segment, q, settings_.thickness, probe);
    // A reading from map nodes that saw no skin within the reach is uncertain: a ray
    // grazing the skin may leave it between nodes (7–20 cm claimed for particles on
    // MakeHuman's knee, which ProjectOut then threw). Read from such nodes alone it says
    // nothing of the depth (the neighbours' shells hold the skin there). Any reading counts
    // only as deep as the body can have come within the step over cloth outside the shell,
    // give or take the thickness and a node spacing: deeper ones, from nodes that
    // saw skin too, pushed MakeHuman's suit by 3–15 cm (2,000 % strain), and the skin
    // triangles decide those (ProjectOut).
    // Only readings inside need the bound (most probes read the particle outside).
    const bool uncertain =
        probe.normal_gap < 0.0 &&
        (probe.blind || -probe.normal_gap > PlausibleDepth(s, x, at_end));
    if (uncertain) {
      if (undecided) undecided->Add(s, probe.normal_gap);
      continue;
    }
    if (probe.normal_gap >= gap) continue;
    gap = probe.normal_gap;
    deepest = s;
    best = probe;
  }
  if (deepest < 0) return false;
  // A joint shell is a sphere: its gradient says nothing of the skin.
  const Eigen::Vector3d local_normal =
      skin_normals_ || segments_[deepest].joint_shell ? best.skin_normal
                    : InsideOutsideGradient(segments_[deepest].superquadric, best.direction)
                          .normalized();
  normal = placement[deepest].to_world.linear() * local_normal;
  body_velocity = BodyVelocity(deepest, x, at_end);
  return true;
}

void SuperquadricCollider::FindContacts(const Points& positions, const Points& velocities, double h,
                                        double margin, std::vector<Contact>& contacts) {
  stats_ = {};
  if (positions.rows() == 0 || segments_.empty()) return;
  Eigen::Vector3d lo, hi;
  BoundingBox(positions, lo, hi);
  const double max_speed = velocities.rowwise().norm().maxCoeff();
  CullSegments(/*at_end=*/false, lo, hi, margin + h * max_speed);
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    const Eigen::Vector3d v = velocities.row(i).transpose();
    double gap;
    Eigen::Vector3d normal, body_velocity;
    if (!DeepestShell(x, false, margin + h * v.norm(), gap, normal, body_velocity)) {
      continue;
    }
    const double body_normal_velocity = body_velocity.dot(normal);
    // Cloth within the margin stays constrained whatever its start velocity, as cloth
    // inside the mesh collider's shell does: the solve may turn back a particle that the
    // start velocity carries off a limb swinging into it (its neighbours pull it), which
    // then ends centimetres inside, and ProjectOut's pushes along the deepest shell thread
    // the cloth through the limb (895 % strain on the kick when only the predicted gap
    // counted; docs/collision.md). A contact that pulls is released in the next step.
    if (gap > margin && gap + h * (v.dot(normal) - body_normal_velocity) > margin) continue;
    Contact contact;
    contact.particle = static_cast<int>(i);
    contact.normal = normal;
    contact.target_normal_velocity = body_normal_velocity - gap / h;
    contact.friction = settings_.friction;
    contacts.push_back(contact);
    ++stats_.num_contacts;
  }
}

namespace {

/// Whether `feature` of `triangle` lies on an edge of `topology` that only one triangle
/// uses (a corner: on one of the triangle's two edges through it).
bool OnOpenEdge(const SurfacePseudonormals& topology, int triangle, TriangleFeature feature) {
  const auto open = [&](int edge) { return topology.neighbour(triangle, edge) < 0; };
  switch (feature) {
    case TriangleFeature::kFace: return false;
    case TriangleFeature::kEdgeAB: return open(0);
    case TriangleFeature::kEdgeBC: return open(1);
    case TriangleFeature::kEdgeCA: return open(2);
    case TriangleFeature::kVertexA: return open(2) || open(0);
    case TriangleFeature::kVertexB: return open(0) || open(1);
    case TriangleFeature::kVertexC: return open(1) || open(2);
  }
  return false;
}

/// The crossings of the ray from `origin` along the unit `direction` (segment frame) with
/// the skin triangles of `skin` (SegmentSkin::ray_crossing, nearest first; the topology's
/// face normals must be those of `skin.local`). False when one cannot be counted: a hit
/// near an edge, or a ray in a triangle's plane. Never throws or allocates.
bool CrossingsAlong(SegmentSkin& skin, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& direction) {
  const SurfacePseudonormals& topology = *skin.topology;
  std::vector<std::pair<double, int>>& crossings = skin.ray_crossing;
  crossings.clear();
  for (int t = 0; t < topology.num_triangles(); ++t) {
    if (!(topology.double_area(t) > 0.0)) continue;  // nothing to cross
    const Eigen::Vector3i& c = skin.triangles[t];
    const Crossing crossing =
        RayCrossing(origin, direction, skin.local[c[0]], skin.local[c[1]], skin.local[c[2]]);
    if (crossing == Crossing::kNone) continue;
    if (crossing == Crossing::kUncertain) return false;
    const Eigen::Vector3d& normal = topology.face_normal(t);
    const double along = normal.dot(direction);
    if (along == 0.0) return false;
    crossings.emplace_back(normal.dot(skin.local[c[0]] - origin) / along,
                           crossing == Crossing::kExit ? 1 : -1);
  }
  std::sort(crossings.begin(), crossings.end());
  return true;
}

/// The winding number of `skin` at `q` (segment frame): the crossings beyond it on the ray
/// from the centre, each exit one, each entry minus one. The same count over the whole ray
/// must find the centre inside (at least 1: it lies inside the body, or in skin folded over
/// it), else a crossing is missing (the ray leaves the skin the segment holds) and the
/// count says nothing. False then, or when a crossing cannot be counted. Never throws or
/// allocates.
bool WindingFromCentre(SegmentSkin& skin, const Eigen::Vector3d& q, int& winding) {
  const double length = q.norm();
  if (!(length > 0.0) || !CrossingsAlong(skin, Eigen::Vector3d::Zero(), q / length)) {
    return false;
  }
  winding = 0;
  int centre = 0;
  for (const auto& [distance, sign] : skin.ray_crossing) {
    centre += sign;
    if (distance > length) winding += sign;
  }
  return centre >= 1;
}

/// The nearest way out of `skin` from `q` (segment frame), inside at `winding`: along each
/// of ExitRayDirections, where the count first falls to 0 on a ray whose crossings add up
/// to `winding` (none missing), and whose count is still 0 `clearance` [m] beyond, where
/// the point is to go (folded skin may lie just past the first way out). As the mesh
/// collider's ProjectOutOfPiece. Its direction and distance [m]; false when no ray finds
/// one within kSkinCheckRadius. Never throws or allocates.
bool WoundExit(SegmentSkin& skin, const Eigen::Vector3d& q, int winding, double clearance,
               Eigen::Vector3d& direction, double& distance) {
  distance = kSkinCheckRadius;
  bool found = false;
  for (const Eigen::Vector3d& ray : ExitRayDirections()) {
    if (!CrossingsAlong(skin, q, ray)) continue;
    int count = winding;
    double first = -1.0;
    bool clear = true;
    for (const auto& [along, sign] : skin.ray_crossing) {
      if (first >= 0.0 && along <= first + clearance) clear = false;
      count -= sign;
      if (count == 0 && first < 0.0) first = along;
    }
    if (count != 0 || first < 0.0 || !clear || first >= distance) continue;
    distance = first;
    direction = ray;
    found = true;
  }
  return found;
}

}  // namespace

bool SuperquadricCollider::SkinShell(const Eigen::Vector3d& x, int s, double& gap,
                                     Eigen::Vector3d& normal, Eigen::Vector3d& body_velocity) {
  SegmentSkin& skin = segments_[s].skin;
  const SurfacePseudonormals& topology = *skin.topology;
  ++stats_.num_skin_checks;
  const Eigen::Vector3d q = end_[s].to_local * x;
  // The nearest point of each closed piece the skin holds, each signed by its own piece:
  // the built-in humanoid's tubes overlap, and a point inside one lies outside the other's
  // buried cap (the body is their union, as in MeshDistance).
  std::fill(skin.piece_distance.begin(), skin.piece_distance.end(), kSkinCheckRadius);
  std::fill(skin.piece_triangle.begin(), skin.piece_triangle.end(), -1);
  for (int t = 0; t < topology.num_triangles(); ++t) {
    const int piece = topology.piece_of(t);
    const Eigen::Vector3i& c = skin.triangles[t];
    // No point of a triangle is farther from a corner than its longest edge.
    const double bound = skin.piece_distance[piece] + skin.edge[t];
    if ((skin.local[c[0]] - q).squaredNorm() > bound * bound) continue;
    const TrianglePoint p =
        ClosestPointOnTriangle(q, skin.local[c[0]], skin.local[c[1]], skin.local[c[2]]);
    const double distance = (q - p.point).norm();
    if (distance >= skin.piece_distance[piece]) continue;
    skin.piece_distance[piece] = distance;
    skin.piece_triangle[piece] = t;
    skin.piece_point[piece] = p;
  }
  if (!skin.corners_current) {
    for (std::size_t k = 0; k < skin.local.size(); ++k) {
      skin.corners.row(static_cast<Eigen::Index>(k)) = skin.local[k].transpose();
    }
    skin.topology->Update(skin.corners, /*vertex_normals=*/false);
    skin.corners_current = true;
  }
  SurfaceSide deepest;
  deepest.signed_distance = std::numeric_limits<double>::infinity();
  for (std::size_t piece = 0; piece < skin.piece_triangle.size(); ++piece) {
    const int t = skin.piece_triangle[piece];
    if (t < 0) continue;
    // The sign from the angle-weighted pseudonormal of the closest feature, right at edges
    // and corners too (as MeshDistance).
    const TrianglePoint& p = skin.piece_point[piece];
    // Where the skin the segment holds ends (a body of one piece, as MakeHuman's, is cut
    // into patches), a nearest point on that edge says nothing of the side: beyond the
    // patch's edge the body goes on, and a point outside it got a sign from a face turned
    // away from it (pushes of 25–85 mm at the suit's shoulders and hips, 1,000 % strain).
    if (OnOpenEdge(topology, t, p.feature)) continue;
    const SurfaceSide side = SideOf(q, p.point, topology.Of(t, p.feature, skin.corners));
    if (side.signed_distance < deepest.signed_distance) deepest = side;
  }
  if (!std::isfinite(deepest.signed_distance)) return false;
  // Skinning moves skin through skin: when a running knee bends, MakeHuman's calf passes
  // through the back of its thigh, and a point inside the calf may lie outside the buried
  // thigh skin nearest it, which is all the nearest point's sign sees (a skirt's hem 10 mm
  // inside the calf, docs/collision.md, "Skin through skin, counted"). Counted along the
  // ray from the centre, which needs the skin's other side in the segment's patch: a body
  // of one piece (the built-in humanoid's closed pieces are signed each by its own).
  int winding = 0;
  Eigen::Vector3d way_out;
  double way_out_distance = 0.0;
  if (deepest.signed_distance > 0.0 && topology.num_pieces() == 1) {
    ++stats_.num_winding_checks;
    if (WindingFromCentre(skin, q, winding) && winding > 0 &&
        WoundExit(skin, q, winding, settings_.thickness, way_out, way_out_distance)) {
      ++stats_.num_buried;
      deepest.signed_distance = -way_out_distance;
      deepest.normal = way_out;
    }
  }
  gap = deepest.signed_distance - settings_.thickness;
  normal = end_[s].to_world.linear() * deepest.normal;
  body_velocity = BodyVelocity(s, x, true);
  return true;
}

void SuperquadricCollider::Undecided::Add(int s, double reading) {
  int k = count < kMax ? count++ : kMax;
  // Insertion, deepest first; a reading shallower than all kMax kept is dropped.
  while (k > 0 && gap[k - 1] > reading) {
    if (k < kMax) segment[k] = segment[k - 1], gap[k] = gap[k - 1];
    --k;
  }
  if (k < kMax) segment[k] = s, gap[k] = reading;
}

bool SuperquadricCollider::Penetration(const Eigen::Vector3d& x, double& gap,
                                       Eigen::Vector3d& normal, Eigen::Vector3d& body_velocity) {
  Undecided undecided;
  if (DeepestShell(x, true, 0.0, gap, normal, body_velocity, &undecided) &&
      gap < -kProjectionTolerance) {
    return true;
  }
  // A point inside a shell that only uncertain readings see is decided by the skin itself:
  // a ray along a limb's axis leaves the skin only at the limb's far end, beyond every
  // shell's reach, so a point deep in the limb near its axis is held by no map (45 mm on
  // MakeHuman's kick; docs/collision.md, "Nodes that saw no skin"). Each segment's
  // triangles speak only for the skin they hold, and the body is their union: a point
  // inside a thigh whose calf's skin, folded into it, is the calf's nearest (a bent knee)
  // is the thigh's to find.
  for (int k = 0; k < undecided.count; ++k) {
    if (SkinShell(x, undecided.segment[k], gap, normal, body_velocity) &&
        gap < -kProjectionTolerance) {
      return true;
    }
  }
  return false;
}

double SuperquadricCollider::ProjectOut(Points& positions, Points& velocities) {
  if (positions.rows() == 0 || segments_.empty()) return 0.0;
  Eigen::Vector3d lo, hi;
  BoundingBox(positions, lo, hi);
  CullSegments(/*at_end=*/true, lo, hi, 0.0);
  double deepest = 0.0;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    // The most penetrated shell only, along its normal: a push along the ray from the centre
    // of an elongated segment (a thigh) would slide the cloth along the limb and tear it
    // where two segments overlap at a joint.
    // A few passes: out of one shell can be into its neighbour's where segments overlap at
    // a joint, and the normal gap of a deep point is only an estimate.
    double least_depth = std::numeric_limits<double>::infinity();
    Eigen::Vector3d least_deep = Eigen::Vector3d::Zero();
    bool settled = false;
    for (int pass = 0; pass < kProjectionPasses; ++pass) {
      const Eigen::Vector3d x = positions.row(i).transpose();
      double gap;
      Eigen::Vector3d normal, body_velocity;
      if (!Penetration(x, gap, normal, body_velocity)) {
        settled = true;
        break;
      }
      if (pass == 0) deepest = std::max(deepest, -gap);
      if (-gap < least_depth) {
        least_depth = -gap;
        least_deep = x;
      }
      positions.row(i) = (x - gap * normal).transpose();
      const double inward = (velocities.row(i).transpose() - body_velocity).dot(normal);
      if (inward < 0.0) velocities.row(i) -= inward * normal.transpose();
    }
    if (settled) continue;
    // Two shells pinching the particle (a crease narrower than two thicknesses, between
    // MakeHuman's thighs) throw it back and forth with every pass, and the last push may
    // land it anywhere (the suit's walk: 1.2–2.1 mm deep in alternate shells for seven
    // passes, then a push of 10.7 mm left it 3.2 mm inside the skin). It goes back to the
    // least deep place it was pushed through, unless where it ended is less deep still.
    double gap;
    Eigen::Vector3d normal, body_velocity;
    if (Penetration(positions.row(i).transpose(), gap, normal, body_velocity) &&
        -gap > least_depth) {
      positions.row(i) = least_deep.transpose();
    }
  }
  return deepest;
}

}  // namespace costume::sim
