#include "sim_core/collision/superquadric_collider.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kPi = std::numbers::pi;
/// Floor of the ray/skin-normal cosine: a ray grazing the skin would otherwise turn a
/// millimetre of thickness into metres of radial shell.
constexpr double kMinSkinCosine = 0.1;

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

/// The node grid on the bounding box's faces: rays, the superquadric's radius along each,
/// the faces' node tables and the node adjacency. The skin fields start on the
/// superquadric itself.
SkinDistanceMap MakeMapGrid(const Superquadric& sq, double spacing) {
  SkinDistanceMap map;
  const Eigen::Vector3d size(sq.a1, sq.a2, sq.a3);
  const auto& n = map.intervals;
  for (int a = 0; a < 3; ++a) {
    map.intervals[a] = std::max(2, static_cast<int>(std::ceil(2.0 * size[a] / spacing)));
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
  map.skin_radius = map.surface_radius;
  map.skin_normal = map.ray;
  return map;
}

/// Bilinear read of the map on the ray through `q` (superquadric frame, q ≠ 0): the skin's
/// radius [m] and its (unnormalised) normal.
void LookUp(const SkinDistanceMap& map, const Eigen::Vector3d& inverse_size,
            const Eigen::Vector3d& q, double& radius, Eigen::Vector3d& normal) {
  int face = 0;
  double s = 0.0, t = 0.0;
  if (!LocateOnBox(q.cwiseProduct(inverse_size), face, s, t)) {
    LocateOnBox(Eigen::Vector3d::UnitZ(), face, s, t);
  }
  const int i = face / 2, nj = map.intervals[(i + 1) % 3], nk = map.intervals[(i + 2) % 3];
  const double fu = 0.5 * (s + 1.0) * nj, fv = 0.5 * (t + 1.0) * nk;
  const int u = std::clamp(static_cast<int>(fu), 0, nj - 1);
  const int v = std::clamp(static_cast<int>(fv), 0, nk - 1);
  const double wu = fu - u, wv = fv - v;
  const int* row = map.face_nodes[face].data() + u * (nk + 1) + v;
  const int n00 = row[0], n01 = row[1], n10 = row[nk + 1], n11 = row[nk + 2];
  const double w00 = (1 - wu) * (1 - wv), w01 = (1 - wu) * wv, w10 = wu * (1 - wv), w11 = wu * wv;
  const auto& r = map.skin_radius;
  radius = w00 * r[n00] + w01 * r[n01] + w10 * r[n10] + w11 * r[n11];
  const auto& m = map.skin_normal;
  normal = w00 * m[n00] + w01 * m[n01] + w10 * m[n10] + w11 * m[n11];
}

/// Draws one skin triangle (corners in the superquadric frame) into the map: every node
/// whose ray crosses it keeps the farther of its current hit and this one. The triangle's
/// rays on a face are those of its central projection onto the face's plane, a triangle
/// whose bounding box gives the candidate nodes; a triangle reaching behind the face's
/// plane projects to an unbounded region, which stretches the box to the face's edges.
void DrawTriangle(const SkinDistanceMap& map, const Eigen::Vector3d& inverse_size,
                  const Eigen::Vector3d (&corner)[3], int triangle, SegmentSkin& skin) {
  const Eigen::Vector3d normal = (corner[1] - corner[0]).cross(corner[2] - corner[0]);
  const double plane = normal.dot(corner[0]);  // the triple product of the corners
  // A triangle whose plane passes through the centre is seen edge on: no ray crosses it
  // at a single point, and its neighbours on the skin hold the rays around it.
  if (std::abs(plane) <= 1e-12 * normal.norm() * corner[0].norm()) return;
  const double orientation = plane > 0.0 ? 1.0 : -1.0;
  const Eigen::Vector3d edge_planes[3] = {orientation * corner[0].cross(corner[1]),
                                          orientation * corner[1].cross(corner[2]),
                                          orientation * corner[2].cross(corner[0])};
  const Eigen::Vector3d p[3] = {corner[0].cwiseProduct(inverse_size),
                                corner[1].cwiseProduct(inverse_size),
                                corner[2].cwiseProduct(inverse_size)};
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int f = 0; f < 6; ++f) {
    const int i = f / 2, j = (i + 1) % 3, k = (i + 2) % 3;
    const double sign = f % 2 == 0 ? 1.0 : -1.0;
    const double w[3] = {sign * p[0][i], sign * p[1][i], sign * p[2][i]};
    if (w[0] <= 0.0 && w[1] <= 0.0 && w[2] <= 0.0) continue;
    double s_lo = kInf, s_hi = -kInf, t_lo = kInf, t_hi = -kInf;
    for (int c = 0; c < 3; ++c) {
      if (w[c] > 0.0) {
        const double s = p[c][j] / w[c], t = p[c][k] / w[c];
        s_lo = std::min(s_lo, s), s_hi = std::max(s_hi, s);
        t_lo = std::min(t_lo, t), t_hi = std::max(t_hi, t);
      }
      const int d = (c + 1) % 3;
      if ((w[c] > 0.0) == (w[d] > 0.0)) continue;
      // The edge crosses the face's plane through the centre: its projection runs off to
      // infinity in the direction of the crossing point's in-face coordinates.
      const double lambda = w[c] / (w[c] - w[d]);
      const Eigen::Vector3d crossing = p[c] + lambda * (p[d] - p[c]);
      if (crossing[j] > 0.0) s_hi = kInf;
      if (crossing[j] < 0.0) s_lo = -kInf;
      if (crossing[k] > 0.0) t_hi = kInf;
      if (crossing[k] < 0.0) t_lo = -kInf;
    }
    if (s_lo > 1.0 || s_hi < -1.0 || t_lo > 1.0 || t_hi < -1.0) continue;
    const int nj = map.intervals[j], nk = map.intervals[k];
    const int u_lo = std::max(0, static_cast<int>(std::ceil(0.5 * (std::max(s_lo, -1.0) + 1.0) * nj - 1e-9)));
    const int u_hi = std::min(nj, static_cast<int>(std::floor(0.5 * (std::min(s_hi, 1.0) + 1.0) * nj + 1e-9)));
    const int v_lo = std::max(0, static_cast<int>(std::ceil(0.5 * (std::max(t_lo, -1.0) + 1.0) * nk - 1e-9)));
    const int v_hi = std::min(nk, static_cast<int>(std::floor(0.5 * (std::min(t_hi, 1.0) + 1.0) * nk + 1e-9)));
    const std::vector<int>& table = map.face_nodes[f];
    for (int u = u_lo; u <= u_hi; ++u) {
      for (int v = v_lo; v <= v_hi; ++v) {
        const int node = table[u * (nk + 1) + v];
        const Eigen::Vector3d& d = map.ray[node];
        // Inside the triangle's cone of rays: on the inner side of its three edge planes.
        // Shared edges are tested with opposite signs by their two triangles, so a ray
        // along an edge is taken by both and none falls between.
        if (edge_planes[0].dot(d) < 0.0 || edge_planes[1].dot(d) < 0.0 ||
            edge_planes[2].dot(d) < 0.0) {
          continue;
        }
        const double radius = plane / normal.dot(d);
        if (radius > skin.hit_radius[node]) {
          skin.hit_radius[node] = radius;
          skin.hit_triangle[node] = triangle;
        }
      }
    }
  }
}

/// Gives the nodes no triangle reached the superquadric's shape raised by the mean offset
/// of their reached (or already filled) neighbours, ring by ring outwards (breadth first).
/// Returns how many nodes were filled.
int FillMissedNodes(SkinDistanceMap& map, SegmentSkin& skin) {
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
    map.skin_radius = map.surface_radius;
    map.skin_normal = map.ray;
    return num_nodes;
  }
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const int node = queue[head];
    double offset = 0.0;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    int count = 0;
    for (int e = map.neighbour_start[node]; e < map.neighbour_start[node + 1]; ++e) {
      const int other = map.neighbours[e];
      if (state[other] == kKnown) {
        offset += map.skin_offset(other);
        normal += map.skin_normal[other];
        ++count;
      } else if (state[other] == kUnknown) {
        state[other] = kQueued;
        queue.push_back(other);
      }
    }
    map.skin_radius[node] = map.surface_radius[node] + offset / count;
    const double length = normal.norm();
    map.skin_normal[node] = length > 0.0 ? Eigen::Vector3d(normal / length) : map.ray[node];
    state[node] = kKnown;
  }
  return static_cast<int>(queue.size());
}

/// Redraws `map` from the skin's corners in the superquadric frame (skin.local). Returns
/// the largest skin radius [m].
double DrawMap(SkinDistanceMap& map, const Eigen::Vector3d& inverse_size, SegmentSkin& skin) {
  std::fill(skin.hit_radius.begin(), skin.hit_radius.end(), -1.0);
  for (std::size_t tri = 0; tri < skin.triangles.size(); ++tri) {
    const Eigen::Vector3i& t = skin.triangles[tri];
    const Eigen::Vector3d corner[3] = {skin.local[t[0]], skin.local[t[1]], skin.local[t[2]]};
    DrawTriangle(map, inverse_size, corner, static_cast<int>(tri), skin);
  }
  double largest = 0.0;
  for (int node = 0; node < map.num_nodes(); ++node) {
    if (skin.hit_radius[node] <= 0.0) continue;
    const Eigen::Vector3i& t = skin.triangles[skin.hit_triangle[node]];
    const Eigen::Vector3d& a = skin.local[t[0]];
    const Eigen::Vector3d normal = (skin.local[t[1]] - a).cross(skin.local[t[2]] - a).normalized();
    // Outward: the side the ray leaves through (winding is not trusted).
    map.skin_normal[node] = normal.dot(map.ray[node]) >= 0.0 ? normal : Eigen::Vector3d(-normal);
    map.skin_radius[node] = skin.hit_radius[node];
  }
  map.num_filled_nodes = FillMissedNodes(map, skin);
  for (double r : map.skin_radius) largest = std::max(largest, r);
  return largest;
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

/// A triangle is drawn into the map of every candidate segment whose centre sees its
/// outside at least this squarely (cosine between its normal and the ray to it) [-], and
/// always into that of the one that sees it most squarely.
constexpr double kSharedViewCosine = 0.5;

/// The candidate segments of a triangle: those its corners belong to and their H-Anim
/// parents and children (segment indices, each once).
int Candidates(const std::array<int, kNumHAnimJoints>& owner,
               const std::vector<SuperquadricSegment>& segments, const int (&mine)[3],
               std::array<int, 3 * kNumHAnimJoints>& out) {
  int count = 0;
  const auto add = [&](int s) {
    if (s >= 0 && std::find(out.begin(), out.begin() + count, s) == out.begin() + count) {
      out[count++] = s;
    }
  };
  for (int c = 0; c < 3; ++c) {
    if (mine[c] < 0) continue;
    add(mine[c]);
    const HAnimJoint joint = segments[mine[c]].segment;
    if (const std::optional<HAnimJoint> parent = HAnimParent(joint)) {
      add(owner[static_cast<int>(*parent)]);
    }
    for (HAnimJoint child : AllHAnimJoints()) {
      if (HAnimParent(child) == joint) add(owner[static_cast<int>(child)]);
    }
  }
  return count;
}

/// Gives every skin triangle to the maps of the segments that see it from outside in the
/// rest pose, among those of its corners and their neighbours: the skinning weights alone
/// would give the underside of the pelvis to the thighs, whose centres below see it from
/// inside, and leave it out of every shell.
void AssignSkin(const Avatar& avatar, std::vector<SuperquadricSegment>& segments) {
  const std::array<int, kNumHAnimJoints> owner = MapOwners(segments);
  const auto& of = avatar.vertex_segments();
  const Points& rest = avatar.rest_vertices();
  std::vector<Eigen::Vector3d> centres;
  for (const SuperquadricSegment& segment : segments) {
    centres.push_back(avatar.skeleton().rest_world()[segment.joint] *
                      segment.superquadric.frame.translation());
  }
  std::vector<std::vector<int>> local(segments.size());
  std::array<int, 3 * kNumHAnimJoints> candidates;
  for (const Eigen::Vector3i& tri : avatar.triangles()) {
    int mine[3];
    for (int c = 0; c < 3; ++c) mine[c] = of[tri[c]] ? owner[static_cast<int>(*of[tri[c]])] : -1;
    const int count = Candidates(owner, segments, mine, candidates);
    const Eigen::Vector3d a = rest.row(tri[0]), b = rest.row(tri[1]), c = rest.row(tri[2]);
    const Eigen::Vector3d normal = (b - a).cross(c - a).normalized();
    const Eigen::Vector3d centroid = (a + b + c) / 3.0;
    double cosines[3 * kNumHAnimJoints];
    double best = -2.0;
    for (int k = 0; k < count; ++k) {
      cosines[k] = normal.dot((centroid - centres[candidates[k]]).normalized());
      best = std::max(best, cosines[k]);
    }
    for (int k = 0; k < count; ++k) {
      if (cosines[k] < best && cosines[k] < kSharedViewCosine) continue;
      const int s = candidates[k];
      SegmentSkin& skin = segments[s].skin;
      if (local[s].empty()) local[s].assign(avatar.num_vertices(), -1);
      Eigen::Vector3i corners;
      for (int m = 0; m < 3; ++m) {
        int& index = local[s][tri[m]];
        if (index < 0) {
          index = static_cast<int>(skin.vertices.size());
          skin.vertices.push_back(tri[m]);
        }
        corners[m] = index;
      }
      skin.triangles.push_back(corners);
    }
  }
  for (SuperquadricSegment& segment : segments) {
    SegmentSkin& skin = segment.skin;
    const int nodes = segment.map.num_nodes();
    skin.local.assign(skin.vertices.size(), Eigen::Vector3d::Zero());
    skin.hit_radius.assign(nodes, -1.0);
    skin.hit_triangle.assign(nodes, -1);
    skin.state.assign(nodes, 0);
    skin.queue.reserve(nodes);
  }
}

SuperquadricSegment MakeSegment(const SegmentSuperquadricFit& fit,
                                const SuperquadricColliderOptions& options) {
  SuperquadricSegment segment;
  segment.segment = fit.segment;
  segment.joint = fit.joint;
  segment.superquadric = fit.fit.superquadric;
  segment.fit_rms = fit.fit.rms_radial_distance;
  segment.num_vertices = fit.num_vertices;
  segment.map = MakeMapGrid(segment.superquadric, options.map_spacing);
  const Superquadric& sq = segment.superquadric;
  segment.inverse_size = Eigen::Vector3d(1.0 / sq.a1, 1.0 / sq.a2, 1.0 / sq.a3);
  return segment;
}

/// Position-correction passes per particle in ProjectOut.
constexpr int kProjectionPasses = 3;

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
  LookUp(segment.map, segment.inverse_size, probe.direction, radius, skin_normal);
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
  for (const SegmentSuperquadricFit& fit : FitGroups(*avatar_, GroupVertices(*avatar_), options)) {
    if (fit.fitted) {
      segments_.push_back(MakeSegment(fit, options));
    } else {
      skipped_.push_back(fit.segment);
    }
  }
  AssignSkin(*avatar_, segments_);
  const std::size_t n = segments_.size();
  start_.resize(n);
  end_.resize(n);
  stale_.assign(n, 0);
  motion_.assign(n, Eigen::Isometry3d::Identity());
  sweep_.assign(n, 0.0);
  active_.reserve(n);
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
    double largest = 0.0;
    for (std::size_t k = 0; k < skin.vertices.size(); ++k) {
      skin.local[k] = to_local * skinned.row(skin.vertices[k]).transpose();
      largest = std::max(largest, skin.local[k].squaredNorm());
    }
    // The map's radii never exceed the farthest corner but where nodes are filled, which
    // RefreshMap adds when it draws.
    segment.bounding_radius =
        std::max(std::sqrt(largest), segment.map_radius) + settings_.thickness / kMinSkinCosine;
    stale_[s] = 1;
  }
}

void SuperquadricCollider::RefreshMap(int s) {
  SuperquadricSegment& segment = segments_[s];
  segment.map_radius = DrawMap(segment.map, segment.inverse_size, segment.skin);
  segment.bounding_radius = std::max(segment.bounding_radius,
                                     segment.map_radius + settings_.thickness / kMinSkinCosine);
  stale_[s] = 0;
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
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    motion_[s] = end_[s].to_world * start_[s].to_local;
    const double angle = Eigen::AngleAxisd(motion_[s].linear()).angle();
    sweep_[s] = (end_[s].to_world.translation() - start_[s].to_world.translation()).norm() +
                segments_[s].bounding_radius * std::abs(angle);
  }
}

Eigen::Vector3d SuperquadricCollider::BodyVelocity(int segment, const Eigen::Vector3d& x,
                                                   bool at_end) const {
  if (inverse_dt_ == 0.0) return Eigen::Vector3d::Zero();
  const Eigen::Isometry3d& motion = motion_[segment];
  if (!at_end) return (motion * x - x) * inverse_dt_;
  return (x - motion.inverse(Eigen::Isometry) * x) * inverse_dt_;
}

void SuperquadricCollider::CullSegments(const std::vector<Placement>& placements,
                                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                        double reach) {
  active_.clear();
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    const Eigen::Vector3d centre = placements[s].to_world.translation();
    const Eigen::Vector3d nearest = centre.cwiseMax(lo).cwiseMin(hi);
    if ((centre - nearest).norm() <= segments_[s].bounding_radius + reach + sweep_[s]) {
      if (stale_[s]) RefreshMap(static_cast<int>(s));
      active_.push_back(static_cast<int>(s));
    }
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
                                        Eigen::Vector3d& body_velocity) {
  const std::vector<Placement>& placement = at_end ? end_ : start_;
  gap = std::numeric_limits<double>::infinity();
  int deepest = -1;
  ShellProbe best;
  for (int s : active_) {
    ++stats_.num_tests;
    const double bound = segments_[s].bounding_radius + reach + sweep_[s];
    if ((x - placement[s].to_world.translation()).squaredNorm() > bound * bound) continue;
    ShellProbe probe;
    ProbeShell(segments_[s], placement[s].to_local * x, settings_.thickness, probe);
    if (probe.normal_gap >= gap) continue;
    gap = probe.normal_gap;
    deepest = s;
    best = probe;
  }
  if (deepest < 0) return false;
  const Eigen::Vector3d local_normal =
      skin_normals_ ? best.skin_normal
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
  CullSegments(start_, lo, hi, margin + h * max_speed);
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    const Eigen::Vector3d v = velocities.row(i).transpose();
    double gap;
    Eigen::Vector3d normal, body_velocity;
    if (!DeepestShell(x, false, margin + h * v.norm(), gap, normal, body_velocity)) continue;
    const double body_normal_velocity = body_velocity.dot(normal);
    if (gap + h * (v.dot(normal) - body_normal_velocity) > margin) continue;
    Contact contact;
    contact.particle = static_cast<int>(i);
    contact.normal = normal;
    contact.target_normal_velocity = body_normal_velocity - gap / h;
    contact.friction = settings_.friction;
    contacts.push_back(contact);
    ++stats_.num_contacts;
  }
}

double SuperquadricCollider::ProjectOut(Points& positions, Points& velocities) {
  if (positions.rows() == 0 || segments_.empty()) return 0.0;
  Eigen::Vector3d lo, hi;
  BoundingBox(positions, lo, hi);
  CullSegments(end_, lo, hi, 0.0);
  double deepest = 0.0;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    // The most penetrated shell only, along its normal: a push along the ray from the centre
    // of an elongated segment (a thigh) would slide the cloth along the limb and tear it
    // where two segments overlap at a joint.
    // A few passes: out of one shell can be into its neighbour's where segments overlap at
    // a joint, and the normal gap of a deep point is only an estimate.
    for (int pass = 0; pass < kProjectionPasses; ++pass) {
      const Eigen::Vector3d x = positions.row(i).transpose();
      double gap;
      Eigen::Vector3d normal, body_velocity;
      if (!DeepestShell(x, true, 0.0, gap, normal, body_velocity) || gap >= 0.0) break;
      if (pass == 0) deepest = std::max(deepest, -gap);
      positions.row(i) = (x - gap * normal).transpose();
      const double inward = (velocities.row(i).transpose() - body_velocity).dot(normal);
      if (inward < 0.0) velocities.row(i) -= inward * normal.transpose();
    }
  }
  return deepest;
}

}  // namespace costume::sim
