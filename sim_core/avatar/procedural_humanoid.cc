#include "sim_core/avatar/procedural_humanoid.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

using J = HAnimJoint;
using Eigen::Vector3d;

/// Fractions of the height at which the joints sit, after anthropometric tables
/// (Drillis & Contini 1966, as tabulated in Winter, "Biomechanics and Motor Control of
/// Human Movement", fig. 4.1): ankle 0.039, knee 0.285, hip 0.52 (joint centre, below the
/// greater trochanter at 0.53), lumbar 0.60, shoulder 0.81, base of neck 0.818.
constexpr double kAnkleHeight = 0.039;
constexpr double kKneeHeight = 0.285;
constexpr double kHipHeight = 0.52;
constexpr double kPelvisHeight = 0.54;
constexpr double kLumbarHeight = 0.60;
constexpr double kShoulderHeight = 0.81;
constexpr double kNeckBaseHeight = 0.818;
constexpr double kUpperArmLength = 0.186;
constexpr double kForearmLength = 0.146;
/// The angle the hanging arms make with the body in the rest pose (A-pose) [rad].
constexpr double kArmAngle = 20.0 * std::numbers::pi / 180.0;
/// The skull base lies this many head radii below the top of the head.
constexpr double kSkullbaseDepth = 1.8;

int Index(J joint) { return static_cast<int>(joint); }

/// World rest positions of every H-Anim joint [m], indexed by HAnimJoint.
using Layout = std::array<Vector3d, kNumHAnimJoints>;

void ValidateMeasures(const HumanoidMeasures& m) {
  const std::string prefix = "humanoid measures.";
  RequireInRange(prefix + "height", m.height, 0.5, 2.5, "m");
  const std::pair<const char*, double> fields[] = {
      {"chest_half_width", m.chest_half_width}, {"waist_half_width", m.waist_half_width},
      {"hip_half_width", m.hip_half_width},     {"chest_half_depth", m.chest_half_depth},
      {"waist_half_depth", m.waist_half_depth}, {"hip_half_depth", m.hip_half_depth},
      {"thigh_radius", m.thigh_radius},         {"calf_radius", m.calf_radius},
      {"upper_arm_radius", m.upper_arm_radius}, {"forearm_radius", m.forearm_radius},
      {"neck_radius", m.neck_radius},           {"head_radius", m.head_radius}};
  for (const auto& [field, value] : fields) {
    // No body part is wider than a quarter of the height; larger values are typos.
    RequireInRange(prefix + field, value, 0.005 * m.height, 0.25 * m.height, "m");
  }
  // The head must leave room for a neck above the shoulders.
  RequireInRange(prefix + "head_radius", m.head_radius, 0.005 * m.height,
                 (1.0 - kNeckBaseHeight - 0.02) * m.height / kSkullbaseDepth, "m");
}

Layout ComputeLayout(const HumanoidMeasures& m) {
  const double h = m.height;
  const double scale = h / 1.75;
  const double hip_x = 0.55 * m.hip_half_width;
  const double shoulder_x = m.chest_half_width + 0.015 * scale;
  Layout p;
  p[Index(J::kHumanoidRoot)] = {0.0, kPelvisHeight * h, 0.0};
  p[Index(J::kSacroiliac)] = p[Index(J::kHumanoidRoot)];
  p[Index(J::kVl5)] = {0.0, kLumbarHeight * h, 0.0};
  p[Index(J::kVc7)] = {0.0, kNeckBaseHeight * h, 0.0};
  p[Index(J::kSkullbase)] = {0.0, h - kSkullbaseDepth * m.head_radius, 0.0};
  for (const double side : {1.0, -1.0}) {  // +1: left (+x)
    const bool left = side > 0.0;
    const Vector3d arm(side * std::sin(kArmAngle), -std::cos(kArmAngle), 0.0);
    const Vector3d shoulder(side * shoulder_x, kShoulderHeight * h, 0.0);
    p[Index(left ? J::kLHip : J::kRHip)] = {side * hip_x, kHipHeight * h, 0.0};
    p[Index(left ? J::kLKnee : J::kRKnee)] = {side * hip_x, kKneeHeight * h, 0.0};
    p[Index(left ? J::kLTalocrural : J::kRTalocrural)] = {side * hip_x, kAnkleHeight * h, 0.0};
    p[Index(left ? J::kLShoulder : J::kRShoulder)] = shoulder;
    p[Index(left ? J::kLElbow : J::kRElbow)] = shoulder + kUpperArmLength * h * arm;
    p[Index(left ? J::kLRadiocarpal : J::kRRadiocarpal)] =
        shoulder + (kUpperArmLength + kForearmLength) * h * arm;
  }
  return p;
}

std::shared_ptr<const Skeleton> BuildSkeleton(const Layout& p) {
  std::vector<Joint> joints;
  for (const J joint : AllHAnimJoints()) {
    Joint entry;
    entry.name = std::string(HAnimName(joint));
    entry.hanim = joint;
    const std::optional<J> parent = HAnimParent(joint);
    // AllHAnimJoints() lists parents first and in enum order, so the H-Anim id is the index.
    entry.parent = parent ? Index(*parent) : -1;
    entry.rest_local.translation() =
        parent ? Vector3d(p[Index(joint)] - p[Index(*parent)]) : p[Index(joint)];
    joints.push_back(std::move(entry));
  }
  return Skeleton::Create("built-in humanoid", std::move(joints));
}

// ---------------------------------------------------------------------------------------
// Surface: one closed tube per body segment, swept along the bone.

/// A cross-section of a segment's tube: at `axial` metres along the axis from the origin,
/// centred at axis point + `offset` (world) [m], half extents along the side and depth
/// directions [m].
struct Station {
  double axial;
  double half_width;
  double half_depth;
  Vector3d offset = Vector3d::Zero();
};

/// The tube of one body segment: stations interpolated by a Catmull-Rom spline, closed at
/// both ends by half-ellipsoid caps reaching `start_cap` / `end_cap` beyond the end stations.
struct SegmentShape {
  J segment;
  Vector3d origin;
  Vector3d axis;       // unit
  Vector3d side_hint;  // the half_width direction, made orthogonal to the axis
  std::vector<Station> stations;
  double start_cap = 0.0;
  double end_cap = 0.0;
  /// Superellipse exponent of the cross-section (2: ellipse; larger: boxier).
  double exponent = 2.0;
  int num_around = 20;
  int num_cap_rings = 5;
};

/// A ring of the tube: the cross-section at `station`, shrunk by `scale` (caps).
struct Ring {
  Station station;
  double scale;
};

/// Catmull-Rom between stations s1 and s2 (s0, s3 their outer neighbours): C1 across
/// stations, so the surface has no crease where its profile changes slope.
Station CatmullRom(const Station& s0, const Station& s1, const Station& s2, const Station& s3,
                   double t) {
  const double t2 = t * t;
  const double t3 = t2 * t;
  const double w0 = -0.5 * t3 + t2 - 0.5 * t;
  const double w1 = 1.5 * t3 - 2.5 * t2 + 1.0;
  const double w2 = -1.5 * t3 + 2.0 * t2 + 0.5 * t;
  const double w3 = 0.5 * t3 - 0.5 * t2;
  auto mix = [&](double Station::*field) {
    return w0 * s0.*field + w1 * s1.*field + w2 * s2.*field + w3 * s3.*field;
  };
  Station out;
  out.axial = mix(&Station::axial);
  out.half_width = mix(&Station::half_width);
  out.half_depth = mix(&Station::half_depth);
  out.offset = w0 * s0.offset + w1 * s1.offset + w2 * s2.offset + w3 * s3.offset;
  return out;
}

/// The rings from the start cap's first ring to the end cap's last, about `spacing` apart
/// along the body.
std::vector<Ring> MakeRings(const SegmentShape& shape, double spacing) {
  const std::vector<Station>& st = shape.stations;
  const int n = static_cast<int>(st.size());
  const int nc = shape.num_cap_rings;
  std::vector<Ring> rings;
  for (int k = 1; k < nc; ++k) {
    const double theta = 0.5 * std::numbers::pi * k / nc;
    Station s = st.front();
    s.axial -= shape.start_cap * std::cos(theta);
    rings.push_back({s, std::sin(theta)});
  }
  rings.push_back({st.front(), 1.0});
  for (int i = 0; i + 1 < n; ++i) {
    const int m =
        std::max(1, static_cast<int>(std::ceil((st[i + 1].axial - st[i].axial) / spacing)));
    const Station& before = st[std::max(i - 1, 0)];
    const Station& after = st[std::min(i + 2, n - 1)];
    for (int j = 1; j <= m; ++j) {
      rings.push_back(
          {CatmullRom(before, st[i], st[i + 1], after, static_cast<double>(j) / m), 1.0});
    }
  }
  for (int k = nc - 1; k >= 1; --k) {
    const double theta = 0.5 * std::numbers::pi * k / nc;
    Station s = st.back();
    s.axial += shape.end_cap * std::cos(theta);
    rings.push_back({s, std::sin(theta)});
  }
  return rings;
}

/// Signed power keeping the sign: the superellipse's parametrisation.
double SignedPower(double value, double exponent) {
  return std::copysign(std::pow(std::abs(value), exponent), value);
}

/// Appends the closed tube of `shape` to `vertices`/`triangles`, triangles counter-clockwise
/// seen from outside: the frame (side, depth, axis) is right-handed and each ring runs
/// counter-clockwise about the axis.
void AppendTube(const SegmentShape& shape, double spacing, std::vector<Vector3d>& vertices,
                std::vector<Eigen::Vector3i>& triangles) {
  const Vector3d& d = shape.axis;
  const Vector3d side = (shape.side_hint - shape.side_hint.dot(d) * d).normalized();
  const Vector3d depth = d.cross(side);
  auto point = [&](const Station& s, double scale, double x, double y) -> Vector3d {
    return shape.origin + s.axial * d + s.offset +
           scale * (x * s.half_width * side + y * s.half_depth * depth);
  };
  const std::vector<Ring> rings = MakeRings(shape, spacing);
  const int m = shape.num_around;
  const int start = static_cast<int>(vertices.size());
  Station pole = shape.stations.front();
  pole.axial -= shape.start_cap;
  vertices.push_back(point(pole, 0.0, 0.0, 0.0));
  const double power = 2.0 / shape.exponent;
  for (const Ring& ring : rings) {
    for (int i = 0; i < m; ++i) {
      const double phi = 2.0 * std::numbers::pi * i / m;
      vertices.push_back(point(ring.station, ring.scale, SignedPower(std::cos(phi), power),
                               SignedPower(std::sin(phi), power)));
    }
  }
  pole = shape.stations.back();
  pole.axial += shape.end_cap;
  vertices.push_back(point(pole, 0.0, 0.0, 0.0));
  const int num_rings = static_cast<int>(rings.size());
  const int first_pole = start;
  const int last_pole = start + 1 + num_rings * m;
  auto at = [&](int ring, int i) { return start + 1 + ring * m + (i % m); };
  for (int i = 0; i < m; ++i) {
    triangles.emplace_back(first_pole, at(0, i + 1), at(0, i));
    for (int r = 0; r + 1 < num_rings; ++r) {
      triangles.emplace_back(at(r, i), at(r, i + 1), at(r + 1, i + 1));
      triangles.emplace_back(at(r, i), at(r + 1, i + 1), at(r + 1, i));
    }
    triangles.emplace_back(at(num_rings - 1, i), at(num_rings - 1, i + 1), last_pole);
  }
}

std::vector<SegmentShape> MakeShapes(const HumanoidMeasures& m, const Layout& p) {
  const double s = m.height / 1.75;  // scale for sizes the measures do not give
  const Vector3d up = Vector3d::UnitY();
  const Vector3d down = -up;
  const Vector3d x = Vector3d::UnitX();
  const Vector3d forward = Vector3d::UnitZ();
  std::vector<SegmentShape> shapes;

  // Pelvis: from the hip joints to just above the lumbar joint; buttocks slightly back.
  {
    const double hip_y = p[Index(J::kLHip)].y();
    const double waist = p[Index(J::kVl5)].y() - hip_y;
    SegmentShape pelvis{J::kSacroiliac, {0.0, hip_y, 0.0}, up, x, {}, 0.06 * s, 0.04 * s, 2.5, 32};
    pelvis.stations = {
        {0.0, m.hip_half_width, m.hip_half_depth, -0.01 * s * forward},
        {0.07 * s, 0.97 * m.hip_half_width, 0.95 * m.hip_half_depth, -0.005 * s * forward},
        {waist, m.waist_half_width, m.waist_half_depth},
        {waist + 0.05 * s, m.waist_half_width, m.waist_half_depth}};
    shapes.push_back(pelvis);
  }
  // Torso: waist, chest, and square shoulders reaching the shoulder joints.
  {
    const Vector3d origin = p[Index(J::kVl5)];
    const double top = p[Index(J::kVc7)].y() - origin.y();
    const double chest = 0.72 * m.height - origin.y();
    SegmentShape torso{J::kVl5, origin, up, x, {}, 0.04 * s, 0.05 * s, 2.5, 32};
    torso.stations = {{-0.03 * s, m.waist_half_width, m.waist_half_depth},
                      {0.02 * s, m.waist_half_width, m.waist_half_depth},
                      {0.5 * chest, 0.5 * (m.waist_half_width + m.chest_half_width),
                       0.5 * (m.waist_half_depth + m.chest_half_depth), 0.005 * s * forward},
                      {chest, m.chest_half_width, m.chest_half_depth, 0.01 * s * forward},
                      // The shoulder girdle, reaching just past the shoulder joints.
                      {top - 0.03 * s, m.chest_half_width + 0.025 * s, 0.8 * m.chest_half_depth}};
    shapes.push_back(torso);
  }
  // Neck and head.
  {
    const Vector3d base = p[Index(J::kVc7)];
    const double length = p[Index(J::kSkullbase)].y() - base.y();
    SegmentShape neck{J::kVc7, base, up, x, {}, 0.05 * s, 0.03 * s, 2.0, 20};
    neck.stations = {{0.0, 1.15 * m.neck_radius, 1.1 * m.neck_radius},
                     {length, m.neck_radius, m.neck_radius, 0.01 * s * forward}};
    shapes.push_back(neck);
    const double r = m.head_radius;
    SegmentShape head{
        J::kSkullbase, p[Index(J::kSkullbase)], up, x, {}, 1.0 * r, 1.2 * r, 2.0, 32, 9};
    head.stations = {{0.6 * r, 0.78 * r, 0.98 * r, 0.02 * s * forward}};
    shapes.push_back(head);
  }
  for (const double side : {1.0, -1.0}) {
    const bool left = side > 0.0;
    const Vector3d hip = p[Index(left ? J::kLHip : J::kRHip)];
    const Vector3d knee = p[Index(left ? J::kLKnee : J::kRKnee)];
    const Vector3d ankle = p[Index(left ? J::kLTalocrural : J::kRTalocrural)];
    const Vector3d shoulder = p[Index(left ? J::kLShoulder : J::kRShoulder)];
    const Vector3d elbow = p[Index(left ? J::kLElbow : J::kRElbow)];
    const Vector3d wrist = p[Index(left ? J::kLRadiocarpal : J::kRRadiocarpal)];
    const double tr = m.thigh_radius;
    const double cr = m.calf_radius;
    SegmentShape thigh{left ? J::kLHip : J::kRHip, hip, down, x, {}, 0.07 * s, 0.045 * s};
    thigh.stations = {{0.0, tr, tr},
                      {0.12 * s, 0.95 * tr, 0.95 * tr},
                      {0.3 * s, 0.8 * tr, 0.78 * tr},
                      {(knee - hip).norm(), 1.05 * cr, 1.05 * cr}};
    shapes.push_back(thigh);
    SegmentShape calf{left ? J::kLKnee : J::kRKnee, knee, down, x, {}, 0.05 * s, 0.03 * s};
    calf.stations = {{0.0, cr, cr},
                     {0.12 * s, cr, 1.05 * cr, -0.012 * s * forward},
                     {0.3 * s, 0.75 * cr, 0.75 * cr},
                     {(ankle - knee).norm(), 0.6 * cr, 0.6 * cr}};
    shapes.push_back(calf);
    // Foot: along +z from the heel; the sole (centre − half depth) is at y = 0 everywhere.
    SegmentShape foot{left ? J::kLTalocrural : J::kRTalocrural,
                      {ankle.x(), 0.0, -0.045 * s},
                      forward,
                      x,
                      {},
                      0.025 * s,
                      0.03 * s,
                      3.0,
                      20};
    auto sole = [&](double axial, double half_width, double half_height) {
      return Station{axial * s, half_width * s, half_height * s, half_height * s * up};
    };
    foot.stations = {sole(0.0, 0.03, 0.035), sole(0.05, 0.037, 0.045), sole(0.13, 0.045, 0.03),
                     sole(0.2, 0.045, 0.02)};
    shapes.push_back(foot);

    const Vector3d arm = (elbow - shoulder).normalized();
    const double ua = m.upper_arm_radius;
    const double fa = m.forearm_radius;
    SegmentShape upper{
        left ? J::kLShoulder : J::kRShoulder, shoulder, arm, x, {}, 0.06 * s, 0.035 * s, 2.0, 16};
    upper.stations = {
        {0.0, 1.15 * ua, 1.1 * ua}, {0.1 * s, ua, ua}, {(elbow - shoulder).norm(), 1.05 * fa, fa}};
    shapes.push_back(upper);
    SegmentShape fore{
        left ? J::kLElbow : J::kRElbow, elbow, arm, x, {}, 0.035 * s, 0.02 * s, 2.0, 16};
    fore.stations = {{0.0, fa, fa},
                     {0.08 * s, 1.1 * fa, 1.05 * fa},
                     {(wrist - elbow).norm(), 0.55 * fa, 0.8 * fa}};
    shapes.push_back(fore);
    // Hand: flat, the palm facing the thigh (thin along the side direction).
    SegmentShape hand{left ? J::kLRadiocarpal : J::kRRadiocarpal,
                      wrist,
                      arm,
                      x,
                      {},
                      0.015 * s,
                      0.05 * s,
                      2.5,
                      16};
    hand.stations = {{0.0, 0.018 * s, 0.03 * s},
                     {0.07 * s, 0.016 * s, 0.042 * s},
                     {0.13 * s, 0.012 * s, 0.038 * s}};
    shapes.push_back(hand);
  }
  return shapes;
}

// ---------------------------------------------------------------------------------------
// Skin weights: blended across each joint so the surface bends without a crease.

/// Where the weight passes from the joint of the segment on the parent side (`inner`) to
/// that of the segment on the child side (`outer`): across a slab of half thickness
/// `half_width` [m] centred on the joint, normal to `axis` (pointing into the outer
/// segment). The blend fades out between `radial_start` and `radial_end` [m] from the axis
/// line, so parts of a segment far from the joint (toes, the jaw) stay rigid.
struct BlendZone {
  J inner;
  J outer;
  Vector3d center;
  Vector3d axis;
  double half_width;
  double radial_start = 1e9;
  double radial_end = 2e9;
};

/// 0 below −1, 1 above 1, C1 in between (zero slope at both ends).
double SmoothStep(double u) {
  const double t = std::clamp(0.5 * (u + 1.0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

/// The outer joint's share of the weight at `v`, before the radial fade.
double OuterShare(const BlendZone& zone, const Vector3d& v, double& radial_factor) {
  const Vector3d rel = v - zone.center;
  const double along = rel.dot(zone.axis);
  const double across = (rel - along * zone.axis).norm();
  radial_factor =
      1.0 -
      SmoothStep(2.0 * (across - zone.radial_start) / (zone.radial_end - zone.radial_start) - 1.0);
  return SmoothStep(along / zone.half_width);
}

std::vector<BlendZone> MakeBlendZones(const HumanoidMeasures& m, const Layout& p) {
  const double s = m.height / 1.75;
  const Vector3d up = Vector3d::UnitY();
  std::vector<BlendZone> zones = {{J::kSacroiliac, J::kVl5, p[Index(J::kVl5)], up, 0.07 * s},
                                  {J::kVl5, J::kVc7, p[Index(J::kVc7)], up, 0.04 * s,
                                   1.3 * m.neck_radius, 1.3 * m.neck_radius + 0.05 * s},
                                  {J::kVc7, J::kSkullbase, p[Index(J::kSkullbase)], up, 0.035 * s,
                                   m.neck_radius, m.neck_radius + 0.035 * s}};
  for (const bool left : {true, false}) {
    auto at = [&](J l, J r) { return left ? l : r; };
    const Vector3d hip = p[Index(at(J::kLHip, J::kRHip))];
    const Vector3d knee = p[Index(at(J::kLKnee, J::kRKnee))];
    const Vector3d ankle = p[Index(at(J::kLTalocrural, J::kRTalocrural))];
    const Vector3d shoulder = p[Index(at(J::kLShoulder, J::kRShoulder))];
    const Vector3d elbow = p[Index(at(J::kLElbow, J::kRElbow))];
    const Vector3d wrist = p[Index(at(J::kLRadiocarpal, J::kRRadiocarpal))];
    const Vector3d arm = (elbow - shoulder).normalized();
    // The hip blend reaches the pelvis only on its own side (up to the midline).
    zones.push_back({J::kSacroiliac, at(J::kLHip, J::kRHip), hip, (knee - hip).normalized(),
                     0.07 * s, std::abs(hip.x()) + 0.01 * s, std::abs(hip.x()) + 0.07 * s});
    zones.push_back({at(J::kLHip, J::kRHip), at(J::kLKnee, J::kRKnee), knee,
                     (ankle - knee).normalized(), 0.06 * s});
    zones.push_back({at(J::kLKnee, J::kRKnee), at(J::kLTalocrural, J::kRTalocrural), ankle,
                     (ankle - knee).normalized(), 0.035 * s, 0.06 * s, 0.1 * s});
    zones.push_back(
        {J::kVc7, at(J::kLShoulder, J::kRShoulder), shoulder, arm, 0.05 * s, 0.07 * s, 0.12 * s});
    zones.push_back(
        {at(J::kLShoulder, J::kRShoulder), at(J::kLElbow, J::kRElbow), elbow, arm, 0.045 * s});
    zones.push_back(
        {at(J::kLElbow, J::kRElbow), at(J::kLRadiocarpal, J::kRRadiocarpal), wrist, arm, 0.03 * s});
  }
  return zones;
}

/// Weights of the vertices [first, end) of the segment `owner`: 1 on the owner, less the
/// shares of the neighbouring segments across the blend zones the owner takes part in.
void AssignWeights(J owner, int first, int end, const std::vector<Vector3d>& vertices,
                   const std::vector<BlendZone>& zones, AvatarData& data) {
  for (int v = first; v < end; ++v) {
    std::vector<std::pair<double, int>> shares;  // (share, joint)
    for (const BlendZone& zone : zones) {
      if (zone.inner != owner && zone.outer != owner) continue;
      double radial = 0.0;
      const double outer = OuterShare(zone, vertices[v], radial);
      const double share = radial * (zone.outer == owner ? 1.0 - outer : outer);
      if (share > 1e-9)
        shares.emplace_back(share, Index(zone.outer == owner ? zone.inner : zone.outer));
    }
    // Keep the largest shares the influence slots hold (the owner takes one).
    std::sort(shares.rbegin(), shares.rend());
    if (shares.size() > kMaxInfluences - 1) shares.resize(kMaxInfluences - 1);
    double others = 0.0;
    for (const auto& share : shares) others += share.first;
    // Overlapping zones (the crotch, where both hips reach) share the vertex fairly.
    const double scale = others > 1.0 ? 1.0 / others : 1.0;
    data.influence_joints.row(v).setConstant(-1);
    data.influence_weights.row(v).setZero();
    data.influence_joints(v, 0) = Index(owner);
    data.influence_weights(v, 0) = std::max(0.0, 1.0 - others * scale);
    for (std::size_t k = 0; k < shares.size(); ++k) {
      data.influence_joints(v, k + 1) = shares[k].second;
      data.influence_weights(v, k + 1) = shares[k].first * scale;
    }
  }
}

}  // namespace

std::shared_ptr<const Skeleton> MakeHumanoidSkeleton(const HumanoidMeasures& measures) {
  ValidateMeasures(measures);
  return BuildSkeleton(ComputeLayout(measures));
}

std::shared_ptr<const Avatar> MakeHumanoid(const HumanoidMeasures& measures) {
  ValidateMeasures(measures);
  const Layout layout = ComputeLayout(measures);
  AvatarData data;
  data.name = "built-in humanoid";
  data.provenance = "procedural (sim_core/avatar/procedural_humanoid.cc), no external asset";
  data.skeleton = BuildSkeleton(layout);

  const double spacing = 0.03 * measures.height / 1.75;
  const std::vector<SegmentShape> shapes = MakeShapes(measures, layout);
  std::vector<Vector3d> vertices;
  std::vector<std::pair<int, int>> ranges;
  for (const SegmentShape& shape : shapes) {
    const int first = static_cast<int>(vertices.size());
    AppendTube(shape, spacing, vertices, data.triangles);
    ranges.emplace_back(first, static_cast<int>(vertices.size()));
  }
  const int n = static_cast<int>(vertices.size());
  data.rest_vertices.resize(n, 3);
  for (int v = 0; v < n; ++v) data.rest_vertices.row(v) = vertices[v].transpose();
  data.influence_joints.resize(n, kMaxInfluences);
  data.influence_weights.resize(n, kMaxInfluences);
  const std::vector<BlendZone> zones = MakeBlendZones(measures, layout);
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    AssignWeights(shapes[i].segment, ranges[i].first, ranges[i].second, vertices, zones, data);
  }
  return Avatar::Create(std::move(data));
}

}  // namespace costume::sim
