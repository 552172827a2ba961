#include "sim_core/collision/superquadric_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

namespace costume::sim {
namespace {

/// Per map drawing, the most rays whose first exit leads into skin again that are followed
/// to where they leave the skin for good, and the most crossings followed along each
/// (MarkFoldedRays, ResolveFoldedRays); the rest keep their first exit.
constexpr int kMaxFoldedRays = 512;
constexpr int kMaxCrossingsPerRay = 8;

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
  // skin.distance holds the corners' norms: a square root a triangle saved.
  return std::abs(plane) > 1e-12 * length * skin.distance[corners[0]] &&
         std::abs(plane) < reach * length;
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

/// RasterizeTriangle's default: every grid box a triangle covers is visited.
constexpr auto kEveryGridBox = [](int, int, int, int, int) { return true; };

/// Calls visit(face, index, lambda) for every map node (a face's grid point `index`) whose
/// ray passes through `triangle`, lambda being the hit in units of the node's point on the
/// box (so the radius is lambda times its distance from the centre); `normal` and `plane`
/// as TriangleWithinReach gives them. The triangle's rays on a face are those of its
/// central projection onto the face's plane, a triangle whose bounding box gives the
/// candidate nodes; a triangle reaching behind the face's plane projects to an unbounded
/// region, which stretches the box to the face's edges. The part of a partly buried
/// triangle inside another piece (SegmentSkin::burial) is clipped off. A face's grid box
/// is visited only where wanted(face, u_lo, u_hi, v_lo, v_hi) (not empty, within the face's
/// grid) says so.
template <typename Visit, typename Wanted = std::remove_cvref_t<decltype(kEveryGridBox)>>
void RasterizeTriangle(const SkinDistanceMap& map, int triangle, const SegmentSkin& skin,
                       const Eigen::Vector3d& normal, double plane, Visit&& visit,
                       const Wanted& wanted = kEveryGridBox) {
  const Eigen::Vector3i& corners = skin.triangles[triangle];
  // Inside the triangle's cone of rays: on the inner side of its three edge planes, whose
  // values are also the barycentric weights of the opposite corners (unnormalised). A
  // triangle the centre sees from behind (an entry) winds the other way. Found once a grid
  // box is to be visited: a third of MakeHuman's triangles hold no grid point.
  Eigen::Vector3d edge_planes[3];
  bool has_edge_planes = false;
  const auto find_edge_planes = [&] {
    const double orientation = plane > 0.0 ? 1.0 : -1.0;
    const Eigen::Vector3d& c0 = skin.local[corners[0]];
    const Eigen::Vector3d& c1 = skin.local[corners[1]];
    const Eigen::Vector3d& c2 = skin.local[corners[2]];
    edge_planes[0] = orientation * c1.cross(c2);
    edge_planes[1] = orientation * c2.cross(c0);
    edge_planes[2] = orientation * c0.cross(c1);
    has_edge_planes = true;
  };
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
    const int u_lo = FirstGridLine(s_lo, nj), u_hi = LastGridLine(s_hi, nj),
              v_lo = FirstGridLine(t_lo, nk), v_hi = LastGridLine(t_hi, nk);
    if (u_lo > u_hi || v_lo > v_hi || !wanted(f, u_lo, u_hi, v_lo, v_hi)) continue;
    if (!has_edge_planes) find_edge_planes();
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

/// Grid points in a row of face `f` of the map's box (its points are stored u-major, a row
/// per u): intervals along the face's second axis, plus one.
int FaceRowLength(const SkinDistanceMap& map, int f) { return map.intervals[(f / 2 + 2) % 3] + 1; }

/// A bound from below on the hits (RasterizeTriangle's lambda) of `triangle` on face `f`:
/// a point's hit on a face is its scaled coordinate along the face's axis, so the nearest
/// corner's bounds every point's (0 when a corner lies behind the face's plane), less a
/// margin for the rounding of the hits RasterizeTriangle computes another way.
double NearestHit(const SegmentSkin& skin, int triangle, int f) {
  const Eigen::Vector3i& corners = skin.triangles[triangle];
  const double sign = f % 2 == 0 ? 1.0 : -1.0;
  double nearest = std::numeric_limits<double>::infinity();
  for (int c = 0; c < 3; ++c) nearest = std::min(nearest, sign * skin.scaled[corners[c]][f / 2]);
  return std::max(nearest * (1.0 - 1e-9), 0.0);
}

/// Whether some ray of face `f`'s grid box [u_lo, u_hi] × [v_lo, v_hi] has its first exit
/// (SegmentSkin::face_hit) beyond `hit`.
bool SomeExitBeyond(const SkinDistanceMap& map, const SegmentSkin& skin, int f, double hit,
                    int u_lo, int u_hi, int v_lo, int v_hi) {
  const int rows = FaceRowLength(map, f);
  const std::vector<double>& exits = skin.face_hit[f];
  for (int u = u_lo; u <= u_hi; ++u) {
    for (int v = v_lo; v <= v_hi; ++v) {
      if (exits[u * rows + v] > hit) return true;
    }
  }
  return false;
}

/// Draws one skin triangle into the map: every node whose ray leaves the skin through it
/// keeps the nearer of its current hit and this one (the ray's first exit), and of equal
/// hits the lower triangle's, whatever order the triangles come in (DrawExits).
void DrawTriangle(const SkinDistanceMap& map, int triangle, SegmentSkin& skin) {
  const Eigen::Vector3d& normal = skin.triangle_side[triangle];
  const double plane = skin.triangle_plane[triangle];
  // Rays entering the skin stop nothing here (MarkFoldedRays looks at them).
  if (!skin.triangle_reached[triangle] || plane < 0.0) return;
  skin.triangle_normal[triangle] = normal.normalized();
  RasterizeTriangle(map, triangle, skin, normal, plane, [&](int f, int index, double lambda) {
    double& hit = skin.face_hit[f][index];
    int& by = skin.face_triangle[f][index];
    if (hit < 0.0 || lambda < hit || (lambda == hit && triangle < by)) {
      hit = lambda;
      by = triangle;
    }
  });
}

/// How far a corner may move in the segment's frame and still count as not moved [m].
/// Skinning puts a vertex weighted to the segment's joint alone back in its place in the
/// segment's frame only to rounding: bit for bit in 13–16 % of the drawings of the walk and
/// the kick, within a nanometre in 47–56 % (docs/collision.md, "The still layer"). A
/// nanometre moves no hit by more than a nanometre, where the map keeps 10 µm steps.
constexpr double kStillTolerance = 1e-9;

/// What ClassifyTriangles found of a triangle, as the still layer records it: 0 stops no
/// ray, 1 an exit, 2 an entry.
char TriangleRole(const SegmentSkin& skin, int triangle) {
  if (!skin.triangle_reached[triangle]) return 0;
  return skin.triangle_plane[triangle] > 0.0 ? 1 : 2;
}

/// What TrackCorners finds: whether a corner of the still layer moved, and how many
/// corners outside it rest.
struct CornerMotion {
  bool layer_moved = false;
  int settled = 0;
};

/// Sets SegmentSkin::resting, whether each corner lies where it was anchored, and anchors
/// the others where they are now. The drawing sees a resting corner exactly where it was
/// anchored (DrawMap puts the skin back after): the triangles through it, in the layer or
/// not, must see the same corner for a ray along their shared edge to be taken by both
/// (RasterizeTriangle). Seen where each is now, a corner differs by rounding between a
/// triangle drawn into the layer and one drawn later, and on the built-in humanoid's kick
/// rays fell between such triangles (hits up to 0.7 mm off).
CornerMotion TrackCorners(SegmentSkin& skin) {
  CornerMotion motion;
  for (std::size_t v = 0; v < skin.local.size(); ++v) {
    const bool rests =
        (skin.local[v] - skin.anchor[v]).cwiseAbs().maxCoeff() <= kStillTolerance;
    skin.resting[v] = rests;
    if (rests) {
      skin.local[v] = skin.anchor[v];
      if (!skin.still[v]) ++motion.settled;
    } else {
      skin.anchor[v] = skin.local[v];
      if (skin.still[v]) motion.layer_moved = true;
    }
  }
  return motion;
}

/// Whether each triangle of the still layer plays the role it played when the layer was
/// drawn: the reach follows the pose, so a triangle may come within it or leave it.
bool LayerRolesHold(const SegmentSkin& skin) {
  for (std::size_t t = 0; t < skin.triangles.size(); ++t) {
    const int triangle = static_cast<int>(t);
    if (skin.in_layer[t] && skin.layer_reached[t] != TriangleRole(skin, triangle)) return false;
  }
  return true;
}

/// Draws the still layer afresh from the resting corners (TrackCorners): the exits of the
/// triangles whose three corners rest are drawn into the map and kept.
void DrawLayer(const SkinDistanceMap& map, SegmentSkin& skin) {
  std::copy(skin.resting.begin(), skin.resting.end(), skin.still.begin());
  for (int f = 0; f < 6; ++f) std::fill(skin.face_hit[f].begin(), skin.face_hit[f].end(), -1.0);
  skin.has_layer = false;
  for (std::size_t t = 0; t < skin.triangles.size(); ++t) {
    const Eigen::Vector3i& c = skin.triangles[t];
    const int triangle = static_cast<int>(t);
    skin.in_layer[t] = skin.still[c[0]] && skin.still[c[1]] && skin.still[c[2]];
    if (!skin.in_layer[t]) continue;
    skin.layer_reached[t] = TriangleRole(skin, triangle);
    skin.has_layer = true;
    DrawTriangle(map, triangle, skin);
  }
  if (!skin.has_layer) return;
  for (int f = 0; f < 6; ++f) {
    std::copy(skin.face_hit[f].begin(), skin.face_hit[f].end(), skin.layer_hit[f].begin());
    std::copy(skin.face_triangle[f].begin(), skin.face_triangle[f].end(),
              skin.layer_triangle[f].begin());
  }
}

/// The layer is drawn again, to take them in, once this many corners outside it have
/// come to rest, as a share of all corners: a drawing of the layer costs a whole drawing.
constexpr double kSettledShareForLayer = 1.0 / 16;

/// Draws every exit triangle into the map (SegmentSkin::face_hit): those of the still layer
/// from the layer while it holds, drawn afresh with it when it does not, then the rest.
/// Linear blend skinning moves only the skin near joints in a segment's frame: the layer
/// holds a third to a half of the exits, whose rasterising was over half of a drawing's
/// time.
void DrawExits(const SkinDistanceMap& map, const CornerMotion& motion, SegmentSkin& skin) {
  const bool holds = skin.has_layer && !motion.layer_moved && LayerRolesHold(skin) &&
                     motion.settled <= kSettledShareForLayer * skin.local.size();
  if (holds) {
    for (int f = 0; f < 6; ++f) {
      std::copy(skin.layer_hit[f].begin(), skin.layer_hit[f].end(), skin.face_hit[f].begin());
      std::copy(skin.layer_triangle[f].begin(), skin.layer_triangle[f].end(),
                skin.face_triangle[f].begin());
    }
  } else {
    DrawLayer(map, skin);
  }
  for (std::size_t t = 0; t < skin.triangles.size(); ++t) {
    if (!skin.in_layer[t]) DrawTriangle(map, static_cast<int>(t), skin);
  }
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
    // Most entries lie beyond the first exits of their rays (into a neighbouring piece):
    // a grid box whose exits all come before the triangle's nearest point is not visited.
    const auto before_an_exit = [&](int f, int u_lo, int u_hi, int v_lo, int v_hi) {
      return SomeExitBeyond(map, skin, f, NearestHit(skin, triangle, f), u_lo, u_hi, v_lo,
                            v_hi);
    };
    RasterizeTriangle(
        map, triangle, skin, skin.triangle_side[tri], plane,
        [&](int f, int index, double lambda) {
          const double hit = skin.face_hit[f][index];
          int& slot = skin.face_slot[f][index];
          if (hit < 0.0 || lambda >= hit || slot >= 0 || skin.num_folded == kMaxFoldedRays) {
            return;
          }
          slot = skin.num_folded++;
          skin.folded_ray[slot] = {f, index};
          skin.folded_count[slot] = 0;
        },
        before_an_exit);
  }
  return skin.num_folded > 0;
}

/// Entries in a row of a face's summed-area table of folded rays (SegmentSkin::folded_sum):
/// the face's row and a leading zero.
int FoldedSumRows(const SkinDistanceMap& map, int face) { return FaceRowLength(map, face) + 1; }

/// Counts each face's folded rays and sums them over its grid (SegmentSkin::folded_sum).
void SumFoldedRays(const SkinDistanceMap& map, SegmentSkin& skin) {
  skin.folded_on_face.fill(0);
  for (int slot = 0; slot < skin.num_folded; ++slot) {
    ++skin.folded_on_face[skin.folded_ray[slot].first];
  }
  for (int f = 0; f < 6; ++f) {
    std::vector<int>& sum = skin.folded_sum[f];
    if (skin.folded_on_face[f] > 0) std::fill(sum.begin(), sum.end(), 0);
  }
  for (int slot = 0; slot < skin.num_folded; ++slot) {
    const auto [f, index] = skin.folded_ray[slot];
    const int row_length = FaceRowLength(map, f);
    const int u = index / row_length, v = index % row_length;
    ++skin.folded_sum[f][(u + 1) * FoldedSumRows(map, f) + v + 1];
  }
  for (int f = 0; f < 6; ++f) {
    if (skin.folded_on_face[f] == 0) continue;
    std::vector<int>& sum = skin.folded_sum[f];
    const int rows = FoldedSumRows(map, f), columns = static_cast<int>(sum.size()) / rows;
    for (int u = 1; u < columns; ++u) {
      for (int v = 1; v < rows; ++v) {
        sum[u * rows + v] += sum[(u - 1) * rows + v] + sum[u * rows + v - 1] -
                             sum[(u - 1) * rows + v - 1];
      }
    }
  }
}

/// How many folded rays face `f`'s grid box [u_lo, u_hi] × [v_lo, v_hi] holds (not empty,
/// within the face's grid).
int FoldedRaysIn(const SkinDistanceMap& map, const SegmentSkin& skin, int f, int u_lo,
                 int u_hi, int v_lo, int v_hi) {
  if (skin.folded_on_face[f] == 0) return 0;
  const std::vector<int>& sum = skin.folded_sum[f];
  const int rows = FoldedSumRows(map, f);
  return sum[(u_hi + 1) * rows + v_hi + 1] - sum[u_lo * rows + v_hi + 1] -
         sum[(u_hi + 1) * rows + v_lo] + sum[u_lo * rows + v_lo];
}

/// Moves each folded ray's hit to where it leaves the skin the map holds for good: its
/// crossings with every triangle, in order, wind it in (entry) and out (exit) from 1 at
/// the centre, and the first exit that takes the count to 0 holds. A ray whose count never
/// gets there (its skin's other side is not in the map) or that crosses more than
/// kMaxCrossingsPerRay triangles keeps its first exit.
void ResolveFoldedRays(const SkinDistanceMap& map, SegmentSkin& skin) {
  SumFoldedRays(map, skin);
  for (std::size_t tri = 0; tri < skin.triangles.size(); ++tri) {
    const int triangle = static_cast<int>(tri);
    if (!skin.triangle_reached[tri]) continue;
    const double plane = skin.triangle_plane[tri];
    const int signed_triangle = plane > 0.0 ? triangle + 1 : -(triangle + 1);
    // A handful of rays are folded: only grid boxes holding one are visited (most
    // triangles' hold none, and rasterising them all was a third of the built-in
    // humanoid's drawing time).
    const auto crosses_folded = [&](int f, int u_lo, int u_hi, int v_lo, int v_hi) {
      return FoldedRaysIn(map, skin, f, u_lo, u_hi, v_lo, v_hi) > 0;
    };
    RasterizeTriangle(
        map, triangle, skin, skin.triangle_side[tri], plane,
        [&](int f, int index, double lambda) {
          const int slot = skin.face_slot[f][index];
          if (slot < 0) return;
          int& count = skin.folded_count[slot];
          if (count < kMaxCrossingsPerRay) {
            skin.folded_crossing[slot * kMaxCrossingsPerRay + count] = {lambda, signed_triangle};
          }
          ++count;
        },
        crosses_folded);
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

}  // namespace

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

namespace {

/// The shell's box and bounding radius from the skin's at the drawing: the shell lies within
/// `thickness` [m] over the least cosine of the skin points.
void BoundDrawnShell(SuperquadricSegment& segment, double thickness) {
  const double shell = thickness / kMinSkinCosine;
  const Eigen::AlignedBox3d& box = segment.drawn_skin_box;
  segment.shell_box = Eigen::AlignedBox3d(box.min().array() - shell, box.max().array() + shell);
  segment.bounding_radius = segment.drawn_skin_farthest + shell;
}

}  // namespace

void DrawMap(SuperquadricSegment& segment, double thickness) {
  SkinDistanceMap& map = segment.map;
  SegmentSkin& skin = segment.skin;
  std::copy(skin.local.begin(), skin.local.end(), skin.unsnapped.begin());
  const CornerMotion motion = TrackCorners(skin);
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
  ClassifyTriangles(segment.reach, skin);
  DrawExits(map, motion, skin);
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
  Eigen::AlignedBox3d box(Eigen::Vector3d::Zero());
  double farthest = 0.0;
  for (int node = 0; node < map.num_nodes(); ++node) {
    box.extend(skin.radius[node] * map.ray[node]);
    farthest = std::max(farthest, skin.radius[node]);
  }
  segment.drawn_skin_box = box;
  segment.drawn_skin_farthest = farthest;
  BoundDrawnShell(segment, thickness);
  // The skin checks (SkinShell) see the skin as it is.
  skin.local.swap(skin.unsnapped);
}

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

void RecordDrawing(const SuperquadricSegment& segment, StoredMapDrawing& stored) {
  stored.skin_box = segment.drawn_skin_box;
  stored.skin_farthest = segment.drawn_skin_farthest;
}

void UseDrawing(const StoredMapDrawing& stored, const StoredMapNode* nodes,
                SuperquadricSegment& segment, double thickness) {
  // A stored drawing was last read a whole pass ago and has left the caches: fetched in one
  // sweep here it streams in, where the queries' scattered reads would each wait for memory.
  constexpr int kNodesPerLine = 64 / sizeof(StoredMapNode);
  for (int node = 0; node < stored.num_nodes; node += kNodesPerLine) {
    __builtin_prefetch(nodes + node);
  }
  segment.nodes = nodes;
  segment.drawn_skin_box = stored.skin_box;
  segment.drawn_skin_farthest = stored.skin_farthest;
  BoundDrawnShell(segment, thickness);
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
  // No corner has been seen yet: the first drawing anchors them all.
  skin.anchor.assign(skin.vertices.size(),
                     Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()));
  skin.still.assign(skin.vertices.size(), 0);
  skin.resting.assign(skin.vertices.size(), 0);
  skin.unsnapped.assign(skin.vertices.size(), Eigen::Vector3d::Zero());
  skin.in_layer.assign(skin.triangles.size(), 0);
  skin.layer_reached.assign(skin.triangles.size(), 0);
  skin.has_layer = false;
  for (int f = 0; f < 6; ++f) {
    skin.face_hit[f].assign(segment.map.face_nodes[f].size(), -1.0);
    skin.face_triangle[f].assign(segment.map.face_nodes[f].size(), -1);
    skin.layer_hit[f].assign(segment.map.face_nodes[f].size(), -1.0);
    skin.layer_triangle[f].assign(segment.map.face_nodes[f].size(), -1);
    skin.face_slot[f].assign(segment.map.face_nodes[f].size(), -1);
    skin.face_folded[f].assign(segment.map.face_nodes[f].size(), 0);
    // A row per grid line along the face's first axis, and a leading zero row.
    const int columns = segment.map.intervals[(f / 2 + 1) % 3] + 2;
    skin.folded_sum[f].assign(static_cast<std::size_t>(columns) * FoldedSumRows(segment.map, f),
                              0);
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

}  // namespace costume::sim
