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
  if (options.map_eta_intervals < 4 || options.map_omega_intervals < 4) {
    throw InputError(where + ": distance map intervals " +
                     std::to_string(options.map_eta_intervals) + "×" +
                     std::to_string(options.map_omega_intervals) + " (allowed: >= 4 each)");
  }
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

// ---- distance map ---------------------------------------------------------------------------

/// A skin triangle in superquadric coordinates with the cone of ray directions it can meet.
struct RayTriangle {
  Eigen::Vector3d v0, e1, e2;
  Eigen::Vector3i vertices{-1, -1, -1};  // the avatar's vertex indices
  Eigen::Vector3d axis;  // unit centroid direction
  double cone_cos = -1;  // rays with direction·axis below this miss the triangle
};

RayTriangle MakeRayTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c) {
  RayTriangle t{a, b - a, c - a, Eigen::Vector3i::Constant(-1), (a + b + c).normalized(), -1.0};
  if (a.norm() > 0 && b.norm() > 0 && c.norm() > 0 && (a + b + c).norm() > 0) {
    // The triangle's directions lie in the spherical hull of its corners' directions, which
    // the cap about the centroid direction through the farthest corner contains when that
    // cap is smaller than a hemisphere.
    const double cone = std::min(
        {t.axis.dot(a.normalized()), t.axis.dot(b.normalized()), t.axis.dot(c.normalized())});
    t.cone_cos = cone > 0.0 ? cone - 1e-9 : -1.0;
  }
  return t;
}

/// Möller–Trumbore from the origin along `d`: distance t > 0 of the hit, or −1; the hit's
/// barycentric coordinates (u, v) of e1 and e2 in `uv`.
double RayHit(const RayTriangle& tri, const Eigen::Vector3d& d, Eigen::Vector2d* uv = nullptr) {
  const Eigen::Vector3d p = d.cross(tri.e2);
  const double det = tri.e1.dot(p);
  if (std::abs(det) < 1e-300) return -1.0;
  const Eigen::Vector3d s = -tri.v0;
  const double u = s.dot(p) / det;
  if (u < 0.0 || u > 1.0) return -1.0;
  const Eigen::Vector3d q = s.cross(tri.e1);
  const double v = d.dot(q) / det;
  if (v < 0.0 || u + v > 1.0) return -1.0;
  const double t = tri.e2.dot(q) / det;
  if (uv) *uv = Eigen::Vector2d(u, v);
  return t > 0.0 ? t : -1.0;
}

int NodeIndex(const SkinDistanceMap& map, int j, int k) { return j * map.num_omega + k; }

/// Gives nodes whose ray missed the skin the mean of their filled neighbours, ring by ring.
void FillMissedNodes(SkinDistanceMap& map, std::vector<char>& known) {
  const int rows = map.num_eta + 1;
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<char> next = known;
    for (int j = 0; j < rows; ++j) {
      for (int k = 0; k < map.num_omega; ++k) {
        const int node = NodeIndex(map, j, k);
        if (known[node]) continue;
        double offset = 0.0;
        Eigen::Vector3d normal = Eigen::Vector3d::Zero();
        int count = 0;
        const int neighbours[4][2] = {{j - 1, k}, {j + 1, k}, {j, k - 1}, {j, k + 1}};
        for (const auto& [nj, nk] : neighbours) {
          if (nj < 0 || nj >= rows) continue;
          const int other = NodeIndex(map, nj, (nk + map.num_omega) % map.num_omega);
          if (!known[other]) continue;
          offset += map.skin_offset[other];
          normal += map.skin_normal[other];
          ++count;
        }
        if (count == 0) continue;
        map.skin_offset[node] = offset / count;
        map.skin_normal[node] = normal.norm() > 0 ? normal.normalized() : Eigen::Vector3d::UnitZ();
        next[node] = 1;
        changed = true;
      }
    }
    known.swap(next);
  }
}

/// Casts every node's ray against `triangles` (superquadric frame); the outermost hit is the
/// skin, so the shell holds everything the ray crosses.
SkinDistanceMap BuildMap(const Superquadric& sq, const std::vector<RayTriangle>& triangles,
                         int num_eta, int num_omega) {
  SkinDistanceMap map;
  map.num_eta = num_eta;
  map.num_omega = num_omega;
  const int num_nodes = (num_eta + 1) * num_omega;
  map.skin_offset.assign(num_nodes, 0.0);
  map.skin_normal.assign(num_nodes, Eigen::Vector3d::UnitZ());
  map.hit_vertices.assign(num_nodes, Eigen::Vector3i::Constant(-1));
  map.hit_weights.assign(num_nodes, Eigen::Vector3d::Zero());
  map.ray.assign(num_nodes, Eigen::Vector3d::UnitZ());
  map.surface_radius.assign(num_nodes, 0.0);
  std::vector<char> known(num_nodes, 0);
  for (int j = 0; j <= num_eta; ++j) {
    for (int k = 0; k < num_omega; ++k) {
      const Eigen::Vector3d surface =
          ParametricSurfacePoint(sq, -kPi / 2 + j * kPi / num_eta, -kPi + k * 2 * kPi / num_omega);
      const Eigen::Vector3d d = surface.normalized();
      const int node = NodeIndex(map, j, k);
      map.ray[node] = d;
      map.surface_radius[node] = surface.norm();
      double farthest = -1.0;
      const RayTriangle* hit = nullptr;
      Eigen::Vector2d uv, hit_uv;
      for (const RayTriangle& tri : triangles) {
        if (d.dot(tri.axis) < tri.cone_cos) continue;
        const double t = RayHit(tri, d, &uv);
        if (t > farthest) {
          farthest = t;
          hit = &tri;
          hit_uv = uv;
        }
      }
      if (!hit) continue;
      map.hit_vertices[node] = hit->vertices;
      map.hit_weights[node] = Eigen::Vector3d(1.0 - hit_uv.x() - hit_uv.y(), hit_uv.x(), hit_uv.y());
      map.skin_offset[node] = farthest - surface.norm();
      // Outward: the side the ray leaves through (winding is not trusted).
      const Eigen::Vector3d normal = hit->e1.cross(hit->e2).normalized();
      map.skin_normal[node] = normal.dot(d) >= 0.0 ? normal : Eigen::Vector3d(-normal);
      known[node] = 1;
    }
  }
  map.num_filled_nodes = num_nodes - static_cast<int>(std::count(known.begin(), known.end(), 1));
  if (map.num_filled_nodes < num_nodes) FillMissedNodes(map, known);
  return map;
}

/// Bilinear interpolation of the map at parametric angles (eta, omega).
void LookUp(const SkinDistanceMap& map, const Eigen::Vector2d& angles, double& offset,
            Eigen::Vector3d& normal) {
  const double fe =
      std::clamp((angles[0] + kPi / 2) / kPi * map.num_eta, 0.0, static_cast<double>(map.num_eta));
  const int j = std::min(static_cast<int>(fe), map.num_eta - 1);
  const double te = fe - j;
  const double fo = (angles[1] + kPi) / (2 * kPi) * map.num_omega;
  const int k_floor = static_cast<int>(std::floor(fo));
  const double to = std::clamp(fo - k_floor, 0.0, 1.0);
  const int k0 = ((k_floor % map.num_omega) + map.num_omega) % map.num_omega;
  const int k1 = (k0 + 1) % map.num_omega;
  const int n00 = NodeIndex(map, j, k0), n01 = NodeIndex(map, j, k1);
  const int n10 = NodeIndex(map, j + 1, k0), n11 = NodeIndex(map, j + 1, k1);
  const double w00 = (1 - te) * (1 - to), w01 = (1 - te) * to, w10 = te * (1 - to), w11 = te * to;
  const auto& o = map.skin_offset;
  offset = w00 * o[n00] + w01 * o[n01] + w10 * o[n10] + w11 * o[n11];
  const auto& n = map.skin_normal;
  normal = w00 * n[n00] + w01 * n[n01] + w10 * n[n10] + w11 * n[n11];
}

SuperquadricSegment BuildSegment(const Avatar& avatar, const SegmentSuperquadricFit& fit,
                                 const std::vector<int>& group,
                                 const SuperquadricColliderOptions& options, double thickness) {
  SuperquadricSegment segment;
  segment.segment = fit.segment;
  segment.joint = fit.joint;
  segment.superquadric = fit.fit.superquadric;
  segment.fit_rms = fit.fit.rms_radial_distance;
  segment.num_vertices = fit.num_vertices;
  const Eigen::Isometry3d to_local =
      (avatar.skeleton().rest_world()[fit.joint] * segment.superquadric.frame).inverse();
  // Skin triangles of the segment: at least two corners in it.
  const auto& segments = avatar.vertex_segments();
  std::vector<RayTriangle> triangles;
  for (const Eigen::Vector3i& tri : avatar.triangles()) {
    int inside = 0;
    for (int c = 0; c < 3; ++c) inside += segments[tri[c]] == fit.segment ? 1 : 0;
    if (inside < 2) continue;
    const auto corner = [&](int c) {
      return Eigen::Vector3d(to_local * avatar.rest_vertices().row(tri[c]).transpose());
    };
    triangles.push_back(MakeRayTriangle(corner(0), corner(1), corner(2)));
    triangles.back().vertices = tri;
  }
  segment.map = BuildMap(segment.superquadric, triangles, options.map_eta_intervals,
                         options.map_omega_intervals);
  // Bounding sphere: the superquadric lies in its box [−a, a]³ (e <= 2), the shell at most
  // the largest offset plus thickness / smallest cosine beyond it, and every skin vertex.
  const Superquadric& sq = segment.superquadric;
  const double largest_offset =
      *std::max_element(segment.map.skin_offset.begin(), segment.map.skin_offset.end());
  double radius = Eigen::Vector3d(sq.a1, sq.a2, sq.a3).norm() + std::max(0.0, largest_offset) +
                  thickness / kMinSkinCosine;
  for (int v : group) {
    radius = std::max(radius, (to_local * avatar.rest_vertices().row(v).transpose()).norm() +
                                  thickness / kMinSkinCosine);
  }
  segment.bounding_radius = segment.rest_bounding_radius = radius;
  segment.rest_max_offset = largest_offset;
  return segment;
}

/// Position-correction passes per particle in ProjectOut.
constexpr int kProjectionPasses = 3;

/// Which distance of the skin from a joint centre its sphere takes: low, so the sphere stays
/// inside the skin where the cross-section is not round (the waist).
constexpr double kJointSpherePercentile = 0.2;

/// Joint spheres for every fitted segment whose parent segment is fitted too.
std::vector<JointSphere> MakeJointSpheres(const Avatar& avatar,
                                          const std::vector<SuperquadricSegment>& segments) {
  std::vector<JointSphere> spheres;
  const Skeleton& skeleton = avatar.skeleton();
  auto fitted = [&](HAnimJoint joint) {
    return std::any_of(segments.begin(), segments.end(),
                       [&](const SuperquadricSegment& s) { return s.segment == joint; });
  };
  for (const SuperquadricSegment& segment : segments) {
    const std::optional<HAnimJoint> parent = HAnimParent(segment.segment);
    if (!parent || !fitted(*parent)) continue;
    const Eigen::Isometry3d& joint = skeleton.rest_world()[segment.joint];
    const Eigen::Vector3d centre = joint.translation();
    const Eigen::Vector3d along =
        (joint * segment.superquadric.frame.translation() - centre).normalized();
    std::vector<double> distances;
    for (int v = 0; v < avatar.num_vertices(); ++v) {
      const Eigen::Vector3d offset = avatar.rest_vertices().row(v).transpose() - centre;
      const double axial = offset.dot(along);
      if (std::abs(axial) > 0.02 || offset.norm() > 0.3) continue;
      distances.push_back((offset - axial * along).norm());
    }
    if (distances.size() < 8) continue;
    const std::size_t rank = static_cast<std::size_t>(kJointSpherePercentile * distances.size());
    std::nth_element(distances.begin(), distances.begin() + rank, distances.end());
    spheres.push_back({segment.joint, distances[rank]});
  }
  return spheres;
}

}  // namespace

std::vector<SegmentSuperquadricFit> FitAvatarSegments(const Avatar& avatar,
                                                      const SuperquadricColliderOptions& options) {
  ValidateOptions(options, "superquadric fit of avatar '" + avatar.name() + "'");
  return FitGroups(avatar, GroupVertices(avatar), options);
}

void ProbeShell(const SuperquadricSegment& segment, const Eigen::Vector3d& q, double thickness,
                ShellProbe& probe) {
  const Superquadric& sq = segment.superquadric;
  const double length = q.norm();
  probe.direction = length > 0.0 ? Eigen::Vector3d(q / length) : Eigen::Vector3d::UnitZ();
  // On the unit direction F is well scaled; r_s = F(d)^(−e1/2) by homogeneity.
  const double surface = std::pow(InsideOutside(sq, probe.direction), -0.5 * sq.e1);
  double offset = 0.0;
  Eigen::Vector3d skin_normal;
  LookUp(segment.map, ParametricAngles(sq, probe.direction), offset, skin_normal);
  const double norm = skin_normal.norm();
  probe.skin_normal = norm > 0.0 ? Eigen::Vector3d(skin_normal / norm) : probe.direction;
  probe.cosine = std::max(probe.direction.dot(probe.skin_normal), kMinSkinCosine);
  probe.shell_radius = surface + offset + thickness / probe.cosine;
  probe.radial_gap = length - probe.shell_radius;
  probe.normal_gap = probe.radial_gap * probe.cosine;
  probe.gradient_normal = InsideOutsideGradient(sq, probe.direction).normalized();
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
  const SegmentGroups groups = GroupVertices(*avatar_);
  for (const SegmentSuperquadricFit& fit : FitGroups(*avatar_, groups, options)) {
    if (!fit.fitted) {
      skipped_.push_back(fit.segment);
      continue;
    }
    segments_.push_back(BuildSegment(*avatar_, fit, groups[static_cast<int>(fit.segment)], options,
                                     settings.thickness));
  }
  const std::size_t n = segments_.size();
  start_.resize(n);
  end_.resize(n);
  motion_.assign(n, Eigen::Isometry3d::Identity());
  sweep_.assign(n, 0.0);
  active_.reserve(n);
  spheres_ = MakeJointSpheres(*avatar_, segments_);
  sphere_start_.assign(spheres_.size(), Eigen::Vector3d::Zero());
  sphere_end_ = sphere_start_;
  SetPose(avatar_->skeleton().rest_world(), end_);
  start_ = end_;
}

void SuperquadricCollider::SetPose(const std::vector<Eigen::Isometry3d>& joint_world,
                                   std::vector<Placement>& out) {
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    out[s].to_world = joint_world[segments_[s].joint] * segments_[s].superquadric.frame;
    out[s].to_local = out[s].to_world.inverse(Eigen::Isometry);
  }
  for (std::size_t k = 0; k < spheres_.size(); ++k) {
    sphere_end_[k] = joint_world[spheres_[k].joint].translation();
  }
}

void SuperquadricCollider::TrackSkin(const Points& skinned) {
  for (std::size_t s = 0; s < segments_.size(); ++s) {
    SuperquadricSegment& segment = segments_[s];
    SkinDistanceMap& map = segment.map;
    const Eigen::Isometry3d& to_local = end_[s].to_local;
    double largest = -std::numeric_limits<double>::infinity();
    for (std::size_t node = 0; node < map.hit_vertices.size(); ++node) {
      const Eigen::Vector3i& v = map.hit_vertices[node];
      if (v[0] < 0) continue;
      const Eigen::Vector3d& w = map.hit_weights[node];
      const Eigen::Vector3d a = to_local * skinned.row(v[0]).transpose();
      const Eigen::Vector3d b = to_local * skinned.row(v[1]).transpose();
      const Eigen::Vector3d c = to_local * skinned.row(v[2]).transpose();
      const Eigen::Vector3d& ray = map.ray[node];
      map.skin_offset[node] = (w[0] * a + w[1] * b + w[2] * c).dot(ray) - map.surface_radius[node];
      const Eigen::Vector3d normal = (b - a).cross(c - a);
      const double length = normal.norm();
      if (length > 0.0) map.skin_normal[node] = (normal.dot(ray) >= 0.0 ? normal : -normal) / length;
      largest = std::max(largest, map.skin_offset[node]);
    }
    segment.bounding_radius =
        segment.rest_bounding_radius + std::max(0.0, largest - segment.rest_max_offset);
  }
}

void SuperquadricCollider::Update(const std::vector<Eigen::Isometry3d>& joint_world,
                                  const Points& skinned_vertices, double dt) {
  const bool usable =
      joint_world.size() >= static_cast<std::size_t>(avatar_->skeleton().num_joints());
  if (usable) {
    start_ = end_;  // same size: no allocation
    sphere_start_ = sphere_end_;
    SetPose(joint_world, end_);
    if (skinned_vertices.rows() == avatar_->num_vertices()) TrackSkin(skinned_vertices);
  }
  const bool moving = usable && has_pose_ && std::isfinite(dt) && dt > 0.0;
  if (usable) has_pose_ = true;
  if (!moving) {
    start_ = end_;
    sphere_start_ = sphere_end_;
  }
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
  for (int s : active_) {
    ++stats_.num_tests;
    const Eigen::Vector3d q = placement[s].to_local * x;
    if (q.norm() > segments_[s].bounding_radius + reach + sweep_[s]) continue;
    ShellProbe probe;
    ProbeShell(segments_[s], q, settings_.thickness, probe);
    if (probe.normal_gap >= gap) continue;
    gap = probe.normal_gap;
    normal = placement[s].to_world.linear() *
             (skin_normals_ ? probe.skin_normal : probe.gradient_normal);
    body_velocity = BodyVelocity(s, x, at_end);
  }
  for (std::size_t k = 0; k < spheres_.size(); ++k) {
    ++stats_.num_tests;
    const Eigen::Vector3d offset = x - (at_end ? sphere_end_[k] : sphere_start_[k]);
    const double distance = offset.norm();
    const double sphere_gap = distance - spheres_[k].radius - settings_.thickness;
    const double sweep = (sphere_end_[k] - sphere_start_[k]).norm();
    if (sphere_gap > reach + sweep || sphere_gap >= gap || distance == 0.0) continue;
    gap = sphere_gap;
    normal = offset / distance;
    body_velocity = (sphere_end_[k] - sphere_start_[k]) * inverse_dt_;
  }
  return gap < std::numeric_limits<double>::infinity();
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
