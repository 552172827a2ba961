#include "sim_core/collision/superquadric_collider.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/superquadric_map.h"
#include "sim_core/collision/surface_geometry.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

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

/// How deep [m] ProjectOut's passes after the first still find a particle before the
/// reading is checked against the segment's own skin (CheckedShell).
constexpr double kRecheckedDepth = 0.001;

/// A pinched particle's way out of a closing crease (EscapePinch): steps [m] and their
/// number. 3 cm covers the creases of MakeHuman's armpits and groin, where a particle
/// thrown between the arm's and the chest's shells ended 3–5 mm inside the skin.
constexpr double kPinchEscapeStep = 0.003;
constexpr int kPinchEscapeSteps = 10;

/// How much nearer than a triangle's longest edge a ray may pass its first corner and
/// still be tested against it (CrossingsAlong) [m]: far above RayCrossing's tolerance for
/// grazing rays, far below any triangle's size.
constexpr double kGrazingMargin = 1e-6;

/// How far from the skin SkinShell searches [m]: a point farther from every triangle of
/// the segment's skin (deeper than a limb is thick) is left undecided.
constexpr double kSkinCheckRadius = 0.1;

}  // namespace

std::vector<SegmentSuperquadricFit> FitAvatarSegments(const Avatar& avatar,
                                                      const SuperquadricColliderOptions& options) {
  ValidateOptions(options, "superquadric fit of avatar '" + avatar.name() + "'");
  return FitGroups(avatar, GroupVertices(avatar), options);
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
  excluded_.assign(n, 0);
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
    skin.corners_current = false;
    BoundShell(static_cast<int>(s));
  }
}

void SuperquadricCollider::BoundShell(int s) {
  SuperquadricSegment& segment = segments_[s];
  const SegmentSkin& skin = segment.skin;
  // The reach follows the skin the segment holds: bending a knee carries the skin at its
  // front away from both the thigh's and the calf's centres.
  double farthest = 0.0;
  for (int k : skin.held) farthest = std::max(farthest, skin.local[k].squaredNorm());
  segment.reach = std::sqrt(farthest) + kReachMargin;
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

void SuperquadricCollider::RefreshMap(int s) {
  SuperquadricSegment& segment = segments_[s];
  stale_[s] = 0;
  const std::uint64_t key = map_cache_.enabled() ? map_cache_.Key(s, segment.skin.local) : 0;
  if (const StoredMapDrawing* stored = map_cache_.Find(key)) {
    UseDrawing(*stored, map_cache_.Nodes(*stored), segment, settings_.thickness);
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

void SuperquadricCollider::Restart() {
  // Update takes the pose it is given next without a velocity, moves every segment's skin
  // (MoveSkin: reach, shell box) and marks every map stale; that is all the state a step
  // reads besides what construction made.
  has_pose_ = false;
  stats_ = {};
  // The store never evicts (skin_map_cache.h): kept full, it would store nothing of the
  // next simulation's motion. One clip's loop takes 40–100 MB of the 256 MB default, so a
  // store up to half full keeps the drawings of the clip played again after a STOP and has
  // room for another clip's.
  const SkinMapCacheStats& store = map_cache_.stats();
  if (2 * store.bytes_used > store.budget_bytes) {
    map_cache_.Clear();
    // A map reused from the store points into it: none may be read before it is redrawn.
    std::fill(stale_.begin(), stale_.end(), 1);
  }
}

void SuperquadricCollider::SetMapMemory(std::size_t bytes) {
  if (bytes == map_cache_.stats().budget_bytes) return;
  const double quantum = map_cache_.quantum();
  map_cache_ = SkinMapCache(0, quantum);  // never two stores reserved at once
  // A map reused from the store points into it: none may be read before it is redrawn.
  std::fill(stale_.begin(), stale_.end(), 1);
  map_cache_ = SkinMapCache(bytes, quantum);
}

void SuperquadricCollider::SetThickness(double thickness) {
  if (thickness == settings_.thickness) return;
  settings_.thickness = thickness;
  // The maps hold the skin, and the stored drawings too: each map is only bounded again,
  // and its shell's box set for the thickness when it is next read.
  for (std::size_t s = 0; s < segments_.size(); ++s) BoundShell(static_cast<int>(s));
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
                                        Undecided* undecided, int* shell) {
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
    if (excluded_[s]) continue;
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
  if (shell) *shell = deepest;
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
    const double relative_normal_velocity = v.dot(normal) - body_normal_velocity;
    // Cloth within the margin stays constrained whatever its start velocity, as cloth
    // inside the mesh collider's shell does: the solve may turn back a particle that the
    // start velocity carries off a limb swinging into it (its neighbours pull it), which
    // then ends centimetres inside, and ProjectOut's pushes along the deepest shell thread
    // the cloth through the limb (895 % strain on the kick when only the predicted gap
    // counted; docs/collision.md). The constraint holds a leaving particle's own normal
    // velocity (ContactNormalVelocity): the solve cannot turn it back, nor is it pulled in.
    if (gap > margin && gap + h * relative_normal_velocity > margin) continue;
    Contact contact;
    contact.particle = static_cast<int>(i);
    contact.normal = normal;
    contact.target_normal_velocity =
        ContactNormalVelocity(body_normal_velocity, gap, relative_normal_velocity, h);
    contact.friction = settings_.friction;
    // The gap is the start's; the shell moves on with the body over the step.
    contact.shell_offset = normal.dot(x) - gap + h * body_normal_velocity;
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
    // No point of a triangle lies farther from a corner than its longest edge (which
    // `edge` bounds): a ray passing farther from the corner, by more than RayCrossing's
    // margin for grazing rays, cannot meet it. (Most of a winding count's time was
    // RayCrossing on triangles far from the ray.)
    const Eigen::Vector3d corner = skin.local[c[0]] - origin;
    const double ahead = corner.dot(direction);
    const double reach = skin.edge[t] + kGrazingMargin;
    if (ahead < -reach || corner.squaredNorm() - ahead * ahead > reach * reach) continue;
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

bool SuperquadricCollider::CheckedShell(const Eigen::Vector3d& x, double checked_depth,
                                        double& gap, Eigen::Vector3d& normal,
                                        Eigen::Vector3d& body_velocity, Undecided& undecided) {
  // A map reads the skin along rays from its centre, and where skin meets skin in a crease
  // (MakeHuman's armpits under the upper arms' maps, its groin under the hips' and the
  // waist's joint shells) it read particles resting on the suit's shell 6–8 mm deeper than
  // the true skin put them (up to 15 mm), and ProjectOut threw them as far: the suit's
  // largest strain 222 % walking, 370 % kicking (docs/collision.md, "Readings checked
  // against the skin"). So a reading inside the skin itself goes to the segment's own
  // triangles, which the map was drawn from (on the suit's walk about 14 skin checks a
  // frame more).
  bool any_excluded = false;
  int shell = -1;
  bool inside = false;
  double skin_gap;
  Eigen::Vector3d skin_normal, skin_velocity;
  for (;;) {
    inside = DeepestShell(x, true, 0.0, gap, normal, body_velocity, &undecided, &shell) &&
             gap < -kProjectionTolerance;
    if (!inside || -gap <= checked_depth) break;
    if (!SkinShell(x, shell, skin_gap, skin_normal, skin_velocity) || skin_gap <= gap) break;
    if (skin_gap < -kProjectionTolerance) {
      gap = skin_gap;
      normal = skin_normal;
      body_velocity = skin_velocity;
      break;
    }
    // Outside the skin this shell holds: the other shells speak for theirs.
    excluded_[shell] = 1;
    any_excluded = true;
  }
  if (any_excluded) std::fill(excluded_.begin(), excluded_.end(), 0);
  return inside;
}

bool SuperquadricCollider::Penetration(const Eigen::Vector3d& x, double checked_depth,
                                       double& gap, Eigen::Vector3d& normal,
                                       Eigen::Vector3d& body_velocity) {
  Undecided undecided;
  const bool certain = CheckedShell(x, checked_depth, gap, normal, body_velocity, undecided);
  // A point inside a shell that only uncertain readings see is decided by the skin itself:
  // a ray along a limb's axis leaves the skin only at the limb's far end, beyond every
  // shell's reach, so a point deep in the limb near its axis is held by no map (45 mm on
  // MakeHuman's kick; docs/collision.md, "Nodes that saw no skin"). Each segment's
  // triangles speak only for the skin they hold, and the body is their union: a point
  // inside a thigh whose calf's skin, folded into it, is the calf's nearest (a bent knee)
  // is the thigh's to find.
  // So is a point that an uncertain reading puts deeper than the certain one: a shell
  // reading it barely inside would push it out of that shell alone, pass after pass (a
  // point 6.7 mm inside a bar folded through itself, read 31 µm inside the knee's shell and
  // 14 mm inside the thigh's and the calf's; docs/collision.md, "A certain reading that hid
  // deeper ones").
  const double least = certain ? gap : -kProjectionTolerance;
  double skin_gap;
  Eigen::Vector3d skin_normal, skin_velocity;
  for (int k = 0; k < undecided.count; ++k) {
    if (certain && undecided.gap[k] >= least) break;  // deepest first
    if (SkinShell(x, undecided.segment[k], skin_gap, skin_normal, skin_velocity) &&
        skin_gap < least) {
      gap = skin_gap;
      normal = skin_normal;
      body_velocity = skin_velocity;
      return true;
    }
  }
  return certain;
}

bool SuperquadricCollider::EscapePinch(const Eigen::Vector3d& from, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, Eigen::Vector3d& out) {
  // Two walls facing each other (a ⋅ b near −1) leave no room within the thickness; their
  // normals lean towards where the crease opens. Walls nearly parallel (a sum under 0.1
  // long) say nothing of which way that is.
  const Eigen::Vector3d opening = a + b;
  if (a.dot(b) > kPinchFacing || opening.norm() < 0.1) return false;
  const Eigen::Vector3d direction = opening.normalized();
  double gap;
  Eigen::Vector3d normal, body_velocity;
  for (int k = 1; k <= kPinchEscapeSteps; ++k) {
    out = from + (k * kPinchEscapeStep) * direction;
    if (!Penetration(out, settings_.thickness, gap, normal, body_velocity)) return true;
  }
  return false;
}

double SuperquadricCollider::ProjectOut(Points& positions, Points& velocities) {
  if (positions.rows() == 0 || segments_.empty()) return 0.0;
  CullSegmentsAtEnd(positions);
  double deepest = 0.0;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    deepest = std::max(deepest, ProjectParticleOut(i, 0.0, positions, velocities));
  }
  return deepest;
}

double SuperquadricCollider::ProjectOut(Points& positions, Points& velocities,
                                        std::span<const int> particles) {
  return ProjectListedOut(positions, velocities, particles, 0.0);
}

double SuperquadricCollider::ProjectOutOfSkin(Points& positions, Points& velocities,
                                              std::span<const int> particles) {
  return ProjectListedOut(positions, velocities, particles, settings_.thickness);
}

double SuperquadricCollider::ProjectListedOut(Points& positions, Points& velocities,
                                              std::span<const int> particles,
                                              double allowance) {
  if (particles.empty() || segments_.empty()) return 0.0;
  CullSegmentsAtEnd(positions);  // all of them: a box over a few would save little
  double deepest = 0.0;
  for (const int i : particles) {
    deepest = std::max(deepest, ProjectParticleOut(i, allowance, positions, velocities));
  }
  return deepest;
}

void SuperquadricCollider::CullSegmentsAtEnd(const Points& positions) {
  Eigen::Vector3d lo, hi;
  BoundingBox(positions, lo, hi);
  CullSegments(/*at_end=*/true, lo, hi, 0.0);
}

double SuperquadricCollider::ProjectParticleOut(Eigen::Index i, double allowance,
                                                Points& positions, Points& velocities) {
  // The most penetrated shell only, along its normal: a push along the ray from the centre
  // of an elongated segment (a thigh) would slide the cloth along the limb and tear it
  // where two segments overlap at a joint.
  // A few passes: out of one shell can be into its neighbour's where segments overlap at
  // a joint, and the normal gap of a deep point is only an estimate.
  double deepest = 0.0;
  Unsettled unsettled;
  for (int pass = 0; pass < kProjectionPasses; ++pass) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    double gap;
    Eigen::Vector3d normal, body_velocity;
    // A first reading is checked where it puts the particle inside the skin itself; a
    // later one, after a push that should have put it on the shell, wherever it still
    // finds it a millimetre in (docs/collision.md, "Readings checked against the skin").
    const double checked_depth = pass == 0 ? settings_.thickness : kRecheckedDepth;
    if (!Penetration(x, checked_depth, gap, normal, body_velocity)) return deepest;
    const double depth = -gap - allowance;
    if (depth <= 0.0) return deepest;
    if (pass == 0) deepest = depth;
    if (depth < unsettled.least_depth) {
      unsettled.least_depth = depth;
      unsettled.least_deep = x;
    }
    unsettled.normal_before = unsettled.last_normal;
    unsettled.last_normal = normal;
    positions.row(i) = (x + depth * normal).transpose();
    RemoveInwardVelocity(i, normal, body_velocity, velocities);
  }
  PlaceUnsettled(i, allowance, unsettled, positions, velocities);
  return deepest;
}

// Two shells pinching the particle (a crease narrower than two thicknesses, between
// MakeHuman's thighs) throw it back and forth with every pass, and the last push may land
// it anywhere (the suit's walk: 1.2–2.1 mm deep in alternate shells for seven passes, then
// a push of 10.7 mm left it 3.2 mm inside the skin). Where the two walls close on it (an
// arm swinging in), no place between them is out: it leaves the crease where it opens, if
// it can. Else it goes midway between the two walls, where it is as deep in each
// (MeshCollider's pinch rule; at the suit's armpit, back to the least deep place left it
// 3.5 mm inside the skin), or back to the least deep place it was pushed through, or
// stays, whichever is least deep.
void SuperquadricCollider::PlaceUnsettled(Eigen::Index i, double allowance,
                                          const Unsettled& unsettled, Points& positions,
                                          Points& velocities) {
  Eigen::Vector3d escaped;
  if (EscapePinch(unsettled.least_deep, unsettled.normal_before, unsettled.last_normal,
                  escaped)) {
    positions.row(i) = escaped.transpose();
    return;
  }
  double gap;
  Eigen::Vector3d normal, body_velocity;
  if (!Penetration(positions.row(i).transpose(), settings_.thickness, gap, normal,
                   body_velocity)) {
    return;
  }
  const double depth = -gap - allowance;
  if (depth <= 0.0) return;
  // Back along the last push by `back`, the depth in both walls to first order.
  const double facing = normal.dot(unsettled.last_normal);
  const double back = facing < kPinchFacing ? PinchMidwayBack(depth, facing) : depth;
  if (back < std::min(unsettled.least_depth, depth)) {
    positions.row(i) -= back * unsettled.last_normal.transpose();
    RemoveInwardVelocity(i, normal, body_velocity, velocities);
  } else if (depth > unsettled.least_depth) {
    positions.row(i) = unsettled.least_deep.transpose();
  }
}

}  // namespace costume::sim
