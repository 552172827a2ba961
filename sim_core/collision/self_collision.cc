#include "sim_core/collision/self_collision.h"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <map>

#include "sim_core/collision/contact.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {

namespace {

using Vec3 = Eigen::Vector3d;

/// Impact-zone passes before giving up (each pass merges at least two zones, so a cloth
/// that needs more is colliding almost everywhere at once; the report then says so).
constexpr int kMaxZonePasses = 64;
/// A coplanarity root counts as a collision when the primitives are this close at that time,
/// as a fraction of the thickness: far below the thickness, far above rounding.
constexpr double kCollisionToleranceFraction = 1e-2;
/// Relative normal motions over a step smaller than this [m] are taken as no motion.
constexpr double kMotionTolerance = 1e-12;
/// The proximity sweeps stop once no pair moves by more than this fraction of the thickness
/// over the step: 4 nm at 4 mm, far below anything visible, and it ends the sweeps early.
constexpr double kProximityToleranceFraction = 1e-6;
/// Pinned particles weigh this many cloths in an impact zone, so a zone holding a pin keeps
/// the pin's velocity (to rounding).
constexpr double kPinnedWeightFactor = 1e9;
/// A pair whose held particles count as infinitely heavy may move none of its others by more
/// than this many times the pair's relative velocity change (HeldMasses); with their own
/// masses, all equal, none moves by more than the change itself.
constexpr double kMaxHeldGain = 2.0;
/// Rings of neighbours around the triangles of a rest tangle that are left out with them:
/// the tangle's line slides over the triangles as the cloth moves.
constexpr int kTangleRings = 2;
/// Gauss-Seidel sweeps of the proximity stage per settings.max_iterations: the sweeps are
/// cheap (cached closest points) and neighbouring pairs need several to agree.
constexpr int kProximitySweepsPerIteration = 4;
/// Edges meeting at a smaller sine than this are parallel for the proximity normal (their
/// common perpendicular is ill defined); so are triangles as thin.
constexpr double kParallelSine = 0.05;
/// A proximity pair counts when its gap is within acos(0.7) ≈ 45° of the face normal or of
/// the edges' common perpendicular (FacingNormal).
constexpr double kMinFacingCosine = 0.7;

Vec3 Row(const Points& p, int i) { return p.row(i).transpose(); }

using Stencil = SelfCollision::Stencil;

Vec3 Combine(const Points& values, const Stencil& s) {
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < 4; ++k) sum += s.weight[k] * Row(values, s.index[k]);
  return sum;
}

/// Σ α_k² / m_k [1/kg] for the stencil's own inverse masses `inverse[4]`: the relative
/// velocity change per unit impulse. 0 if all pinned.
double InverseEffectiveMass(const Stencil& s, const double inverse[4]) {
  double sum = 0.0;
  for (int k = 0; k < 4; ++k) sum += s.weight[k] * s.weight[k] * inverse[k];
  return sum;
}

/// The stencil's particles' entries of `inverse_mass` [1/kg].
struct StencilMasses {
  StencilMasses(const Stencil& s, const Eigen::VectorXd& inverse_mass) {
    for (int k = 0; k < 4; ++k) inverse[k] = inverse_mass[s.index[k]];
  }
  double inverse[4];
};

double InverseEffectiveMass(const Stencil& s, const Eigen::VectorXd& inverse_mass) {
  return InverseEffectiveMass(s, StencilMasses(s, inverse_mass).inverse);
}

/// Changes the stencil's relative velocity along unit `direction` by `delta` [m/s] with one
/// impulse split by the weights and the stencil's inverse masses `inverse[4]` (momentum-
/// conserving unless a held particle's infinite mass stands for the body's).
void ApplyRelativeChange(Points& velocities, const Stencil& s, const double inverse[4],
                         const Vec3& direction, double delta) {
  const double k = InverseEffectiveMass(s, inverse);
  if (k <= 0.0 || delta == 0.0) return;
  const double impulse = delta / k;
  for (int i = 0; i < 4; ++i) {
    velocities.row(s.index[i]) += (s.weight[i] * inverse[i] * impulse) * direction.transpose();
  }
}

void ApplyRelativeChange(Points& velocities, const Stencil& s, const Eigen::VectorXd& inverse_mass,
                         const Vec3& direction, double delta) {
  ApplyRelativeChange(velocities, s, StencilMasses(s, inverse_mass).inverse, direction, delta);
}

/// Bridson §7.2 friction: the relative tangential velocity shrinks by μ·(normal velocity
/// change), never past zero.
void ApplyFriction(Points& velocities, const Stencil& s, const Eigen::VectorXd& inverse_mass,
                   const Vec3& normal, double normal_change, double friction) {
  if (friction <= 0.0 || normal_change <= 0.0) return;
  const Vec3 relative = Combine(velocities, s);
  const Vec3 tangential = relative - relative.dot(normal) * normal;
  const double speed = tangential.norm();
  if (speed <= 0.0) return;
  ApplyRelativeChange(velocities, s, inverse_mass, tangential / speed,
                      -std::min(speed, friction * normal_change));
}

/// Barycentric weights (u, v, w) of the point of triangle abc closest to p
/// (Ericson, Real-Time Collision Detection §5.1.5).
Vec3 ClosestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {1, 0, 0};
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return {1, 0, 0};  // degenerate triangle: any vertex will do
  const double v = vb / sum, w = vc / sum;
  return {1 - v - w, v, w};
}

double Clamp01(double x) { return std::clamp(x, 0.0, 1.0); }

/// Parameters (s, t) of the closest points p1 + s(q1 − p1), p2 + t(q2 − p2) of two segments
/// (Ericson §5.1.9); parallel segments get s = 0.
std::pair<double, double> ClosestOnSegments(const Vec3& p1, const Vec3& q1, const Vec3& p2,
                                            const Vec3& q2) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  constexpr double kTiny = 1e-30;
  if (a <= kTiny && e <= kTiny) return {0.0, 0.0};
  if (a <= kTiny) return {0.0, Clamp01(f / e)};
  const double c = d1.dot(r);
  if (e <= kTiny) return {Clamp01(-c / a), 0.0};
  const double b = d1.dot(d2), denominator = a * e - b * b;
  double s = denominator > 0.0 ? Clamp01((b * f - c * e) / denominator) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0.0) {
    t = 0.0;
    s = Clamp01(-c / a);
  } else if (t > 1.0) {
    t = 1.0;
    s = Clamp01((b - c) / a);
  }
  return {s, t};
}

/// The four particles of a pair in stencil order (point, triangle; or edge A, edge B).
void PairIndices(const SelfCollision::PrimitivePair& pair, const ClothModel& model,
                 const std::vector<std::pair<int, int>>& edges, int index[4]) {
  if (pair.kind == SelfCollision::PrimitivePair::kPointTriangle) {
    const Eigen::Vector3i& t = model.triangles()[pair.b];
    index[0] = pair.a;
    index[1] = t[0];
    index[2] = t[1];
    index[3] = t[2];
  } else {
    index[0] = edges[pair.a].first;
    index[1] = edges[pair.a].second;
    index[2] = edges[pair.b].first;
    index[3] = edges[pair.b].second;
  }
}

/// The closest points of a pair at positions x (stencil order): weights, gap and normal.
struct Proximity {
  Stencil stencil;
  Vec3 gap = Vec3::Zero();
  double distance = 0.0;
};

Proximity Closest(SelfCollision::PrimitivePair::Kind kind, const int index[4], const Vec3 x[4]) {
  Proximity result;
  for (int k = 0; k < 4; ++k) result.stencil.index[k] = index[k];
  double* w = result.stencil.weight;
  if (kind == SelfCollision::PrimitivePair::kPointTriangle) {
    const Vec3 b = ClosestOnTriangle(x[0], x[1], x[2], x[3]);
    w[0] = 1.0;
    w[1] = -b[0];
    w[2] = -b[1];
    w[3] = -b[2];
  } else {
    const auto [s, t] = ClosestOnSegments(x[0], x[1], x[2], x[3]);
    w[0] = 1.0 - s;
    w[1] = s;
    w[2] = -(1.0 - t);
    w[3] = -t;
  }
  for (int k = 0; k < 4; ++k) result.gap += w[k] * x[k];
  result.distance = result.gap.norm();
  return result;
}

/// The plane normal of the pair at x: the triangle's, or the edges' common perpendicular.
Vec3 PlaneNormal(SelfCollision::PrimitivePair::Kind kind, const Vec3 x[4]) {
  if (kind == SelfCollision::PrimitivePair::kPointTriangle) {
    return (x[2] - x[1]).cross(x[3] - x[1]);
  }
  return (x[1] - x[0]).cross(x[3] - x[2]);
}

/// A unit normal from the second primitive towards the first: along the gap when there is
/// one, else the plane normal, else any axis; `fallback_side` picks the sign in the last two
/// cases (the normal is flipped to make fallback_side·n >= 0).
Vec3 ContactNormal(const Proximity& p, const Vec3& plane_normal, const Vec3& fallback_side) {
  if (p.distance > 1e-12) return p.gap / p.distance;
  Vec3 n = plane_normal.norm() > 1e-30 ? Vec3(plane_normal.normalized()) : Vec3::UnitY();
  if (n.dot(fallback_side) < 0.0) n = -n;
  return n;
}

/// A proximity pair's normal and distance along it, or false for a pair that meets only at
/// a rim. The normal is the face's (point–triangle) or the edges' common perpendicular
/// (edge–edge), signed to the first primitive's side; the distance is the gap along it.
/// Along the gap itself, pairs whose closest point is clamped to a corner or an edge's end
/// lean their normals over: a patch lying on a sheet met such pairs wherever its corners
/// passed the sheet's edges, and each stopped part of its sliding as if it were approach,
/// so a frictionless patch stuck on a 30° slope (docs/collision.md, "Self-collision").
/// Pairs whose gap leaves the face normal by more than ~45° are left to the rims' own pairs
/// and to continuous detection, as in Bridson's proximity test, which asks for the point's
/// projection to fall on the face.
bool FacingNormal(SelfCollision::PrimitivePair::Kind kind, const Vec3 x[4], const Proximity& p,
                  const Vec3& fallback_side, Vec3* normal, double* distance) {
  const Vec3 plane_normal = PlaneNormal(kind, x);
  // |a × b| against |a|·|b|: the sine between the edges, or twice the triangle's area
  // against its two sides' product.
  const bool triangle = kind == SelfCollision::PrimitivePair::kPointTriangle;
  const double scale = triangle ? (x[2] - x[1]).norm() * (x[3] - x[1]).norm()
                                : (x[1] - x[0]).norm() * (x[3] - x[2]).norm();
  const double plane_norm = plane_normal.norm();
  if (!(plane_norm > kParallelSine * scale)) {
    // Near-parallel edges have no common perpendicular, and their gap leans with their
    // sideways offset: two sheets whose lattices lie edge over edge caught on every pair
    // (a frictionless patch slid at 2.94 m/s² where g sin 30° is 4.90). Their ends' pairs
    // with the faces beside the other edge hold them.
    if (!triangle) return false;
    *normal = ContactNormal(p, plane_normal, fallback_side);  // a sliver
    *distance = p.distance;
    return true;
  }
  const Vec3 n = plane_normal / plane_norm;
  const double along = p.gap.dot(n);
  if (p.distance > 1e-12 && std::abs(along) < kMinFacingCosine * p.distance) return false;
  if (p.distance > 1e-12) {
    *normal = along < 0.0 ? Vec3(-n) : n;
  } else {
    *normal = ContactNormal(p, plane_normal, fallback_side);  // touching: the side decides
  }
  *distance = std::abs(along);
  return true;
}

/// Roots of a·t³ + b·t² + c·t + d in [0, 1], ascending; also the ends and turning points
/// where the cubic nearly vanishes (grazing contacts). Returns how many (at most 6).
int CubicRootsInUnitInterval(double a, double b, double c, double d, double roots[6]) {
  const auto f = [&](double t) { return ((a * t + b) * t + c) * t + d; };
  const double scale = std::abs(a) + std::abs(b) + std::abs(c) + std::abs(d);
  int count = 0;
  if (scale == 0.0) {  // coplanar all step long: the distance tests decide
    roots[count++] = 0.0;
    roots[count++] = 1.0;
    return count;
  }
  const double tolerance = 1e-12 * scale;
  // Split [0, 1] at the turning points (roots of 3a t² + 2b t + c) into monotone pieces.
  double knots[4];
  int num_knots = 0;
  knots[num_knots++] = 0.0;
  const double qa = 3.0 * a, qb = 2.0 * b, qc = c;
  if (std::abs(qa) > 1e-14 * scale) {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0.0) {
      const double q = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
      double r1 = q / qa, r2 = q != 0.0 ? qc / q : r1;
      if (r1 > r2) std::swap(r1, r2);
      if (r1 > 0.0 && r1 < 1.0) knots[num_knots++] = r1;
      if (r2 > 0.0 && r2 < 1.0 && r2 != r1) knots[num_knots++] = r2;
    }
  } else if (qb != 0.0) {
    const double r = -qc / qb;
    if (r > 0.0 && r < 1.0) knots[num_knots++] = r;
  }
  knots[num_knots++] = 1.0;
  for (int k = 0; k < num_knots; ++k) {
    if (k + 1 < num_knots) {
      double lo = knots[k], hi = knots[k + 1];
      double f_lo = f(lo);
      if (std::abs(f_lo) <= tolerance) roots[count++] = lo;
      const double f_hi = f(hi);
      if ((f_lo < 0.0 && f_hi > 0.0) || (f_lo > 0.0 && f_hi < 0.0)) {
        for (int i = 0; i < 60; ++i) {  // bisection: the piece is monotone
          const double mid = 0.5 * (lo + hi), f_mid = f(mid);
          if ((f_mid < 0.0) == (f_lo < 0.0)) {
            lo = mid;
            f_lo = f_mid;
          } else {
            hi = mid;
          }
        }
        roots[count++] = 0.5 * (lo + hi);
      }
    } else if (std::abs(f(knots[k])) <= tolerance) {
      roots[count++] = knots[k];
    }
  }
  return count;  // ascending: knots and bisection roots come in order
}

/// The coplanarity cubic of four particles moving x_k + t·dx_k, t ∈ [0, 1] (Bridson §6):
/// (x1 − x0) × (x2' − x0') · (x3 − x0) style triple product whose zeros are the times when
/// the point lies in the triangle's plane (or the two edges' lines meet a common plane).
void CoplanarityCubic(SelfCollision::PrimitivePair::Kind kind, const Vec3 x[4], const Vec3 dx[4],
                      double coefficients[4]) {
  Vec3 a0, a1, b0, b1, c0, c1;
  if (kind == SelfCollision::PrimitivePair::kPointTriangle) {  // (x2−x1) × (x3−x1) · (x0−x1)
    a0 = x[2] - x[1], a1 = dx[2] - dx[1];
    b0 = x[3] - x[1], b1 = dx[3] - dx[1];
    c0 = x[0] - x[1], c1 = dx[0] - dx[1];
  } else {  // (x1−x0) × (x3−x2) · (x2−x0)
    a0 = x[1] - x[0], a1 = dx[1] - dx[0];
    b0 = x[3] - x[2], b1 = dx[3] - dx[2];
    c0 = x[2] - x[0], c1 = dx[2] - dx[0];
  }
  const Vec3 n0 = a0.cross(b0), n1 = a0.cross(b1) + a1.cross(b0), n2 = a1.cross(b1);
  coefficients[0] = n2.dot(c1);
  coefficients[1] = n1.dot(c1) + n2.dot(c0);
  coefficients[2] = n0.dot(c1) + n1.dot(c0);
  coefficients[3] = n0.dot(c0);
}

/// Collects the triangle pairs whose boxes overlap.
struct PairCollector : btDbvt::ICollide {
  std::vector<std::pair<int, int>>* pairs = nullptr;
  void Process(const btDbvtNode* a, const btDbvtNode* b) {
    pairs->emplace_back(a->dataAsInt, b->dataAsInt);
  }
  void Process(const btDbvtNode*) {}
};

/// The leaves overlapping changed triangle `triangle`, each pair once: a pair of two
/// changed triangles is left to the one of lower index.
struct ChangedPairCollector : btDbvt::ICollide {
  int triangle = 0;
  const std::vector<char>* changed = nullptr;
  std::vector<std::pair<int, int>>* pairs = nullptr;
  void Process(const btDbvtNode* leaf) {
    const int other = leaf->dataAsInt;
    if (other == triangle || ((*changed)[other] && other < triangle)) return;
    pairs->emplace_back(triangle, other);
  }
};

/// Whether box a of (lo_a, hi_a) and box b of (lo_b, hi_b) (rows of corners) come within
/// `margin` of each other.
bool RowsOverlap(const Points& lo_a, const Points& hi_a, int a, const Points& lo_b,
                 const Points& hi_b, int b, double margin) {
  for (int d = 0; d < 3; ++d) {
    if (lo_a(a, d) > hi_b(b, d) + margin || lo_b(b, d) > hi_a(a, d) + margin) return false;
  }
  return true;
}

int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // path halving
    i = parent[i];
  }
  return i;
}

std::vector<std::pair<int, int>> UniqueEdges(const ClothModel& model) {
  std::map<std::pair<int, int>, int> seen;
  std::vector<std::pair<int, int>> edges;
  for (const Eigen::Vector3i& t : model.triangles()) {
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      const std::pair<int, int> key(std::min(a, b), std::max(a, b));
      if (seen.emplace(key, static_cast<int>(edges.size())).second) edges.push_back(key);
    }
  }
  return edges;
}

double Orient(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).cross(c - a).dot(d - a);
}

// Why the tolerance on the plane's side: a lattice column running on past a triangle's edge
// lies in that triangle's plane, and the rounding of its orientations (±1e-22 m³) counted 2
// edges of the built-in skirt's rest shape as crossing. 1e-12 of the largest term is far
// above rounding (1e-16) and far below anything a cloth does.
bool SegmentCrossesTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b,
                            const Vec3& c) {
  const double sp = Orient(a, b, c, p), sq = Orient(a, b, c, q);
  const double in_plane = 1e-12 * (b - a).norm() * (c - a).norm() *
                          std::max((p - a).norm(), (q - a).norm());
  if (!((sp > in_plane && sq < -in_plane) || (sp < -in_plane && sq > in_plane))) return false;
  const double o1 = Orient(p, q, a, b), o2 = Orient(p, q, b, c), o3 = Orient(p, q, c, a);
  return (o1 > 0.0 && o2 > 0.0 && o3 > 0.0) || (o1 < 0.0 && o2 < 0.0 && o3 < 0.0);
}

/// Whether an edge of triangle `a` that shares no particle with triangle `b` passes through
/// `b`, at `positions` (SegmentCrossesTriangle).
bool AnEdgeCrosses(const Points& positions, const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
  for (int k = 0; k < 3; ++k) {
    const int p = a[k], q = a[(k + 1) % 3];
    if (p == b[0] || p == b[1] || p == b[2] || q == b[0] || q == b[1] || q == b[2]) continue;
    if (SegmentCrossesTriangle(Row(positions, p), Row(positions, q), Row(positions, b[0]),
                               Row(positions, b[1]), Row(positions, b[2]))) {
      return true;
    }
  }
  return false;
}

}  // namespace

void ValidateSelfCollisionSettings(const SelfCollisionSettings& settings,
                                   const std::string& context) {
  RequirePositive(context + ".thickness", settings.thickness, "m");
  RequireNonNegative(context + ".friction", settings.friction, "");
  for (std::size_t i = 0; i < settings.particle_friction.size(); ++i) {
    const double mu = settings.particle_friction[i];
    if (!(mu < 0.0 || std::isfinite(mu))) {  // negative: the default; NaN and +inf refused
      throw InputError(context + ".particle_friction[" + std::to_string(i) + "] = " +
                       std::to_string(mu) + ": allowed is a finite value >= 0, or < 0 for " +
                       "friction");
    }
  }
  RequireNonNegative(context + ".stiffness", settings.stiffness, "N/m");
  RequireInRange(context + ".max_iterations", settings.max_iterations, 0, 1000, "");
}

namespace {

/// Throws InputError, naming `context`, for per-particle frictions of the wrong count or a
/// triangle that repeats a particle.
void ValidateClothForSelfCollision(const ClothModel& model, const SelfCollisionSettings& settings,
                                   const std::string& context) {
  const int n = model.num_particles();
  if (!settings.particle_friction.empty() &&
      settings.particle_friction.size() != static_cast<std::size_t>(n)) {
    throw InputError(context + ": particle_friction has " +
                     std::to_string(settings.particle_friction.size()) +
                     " values: allowed are none or one per particle (" + std::to_string(n) + ")");
  }
  const auto& triangles = model.triangles();
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      throw InputError(context + ": triangles[" + std::to_string(t) + "] = (" +
                       std::to_string(tri[0]) + ", " + std::to_string(tri[1]) + ", " +
                       std::to_string(tri[2]) + ") repeats a particle: allowed are three " +
                       "distinct particles");
    }
  }
}

}  // namespace

/// Bullet's traversal stack, kept between calls (Bullet stays out of the header).
struct SelfCollision::TreeStack {
  btNodeStack nodes;
};

SelfCollision::SelfCollision(std::shared_ptr<const ClothModel> model,
                             const SelfCollisionSettings& settings)
    : model_(std::move(model)), settings_(settings), tree_(std::make_unique<btDbvt>()) {
  const std::string context = "self-collision of '" + model_->name() + "'";
  ValidateSelfCollisionSettings(settings_, context);
  ValidateClothForSelfCollision(*model_, settings_, context);
  const int n = model_->num_particles();
  inverse_mass_.resize(n);
  for (int i = 0; i < n; ++i) {
    inverse_mass_[i] = model_->is_pinned()[i] ? 0.0 : 1.0 / model_->masses()[i];
  }
  AssignOwnership();
  BuildTree();
  ReserveScratch();
  FindRestTangles();
}

// Why: a garment whose own rest shape passes through itself (the MakeHuman casual suit: 38
// edges through it as modelled) cannot be kept on the side it started on, because it
// started on both; resolving those pairs locked the layers together and stretched the suit.
void SelfCollision::FindRestTangles() {
  std::vector<char> tangled = ParticlesOfRestCrossings();
  for (int ring = 0; ring < kTangleRings; ++ring) {
    std::vector<char> grown = tangled;
    for (const auto& [a, b] : edges_) {
      if (tangled[a] || tangled[b]) grown[a] = grown[b] = 1;
    }
    tangled.swap(grown);
  }
  const auto& triangles = model_->triangles();
  triangle_tangled_.assign(triangles.size(), 0);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    triangle_tangled_[t] = tangled[tri[0]] || tangled[tri[1]] || tangled[tri[2]];
  }
}

int SelfCollision::num_rest_tangled_triangles() const {
  return static_cast<int>(std::count(triangle_tangled_.begin(), triangle_tangled_.end(), 1));
}

std::vector<char> SelfCollision::ParticlesOfRestCrossings() {
  const Points& rest = model_->rest_positions();
  const auto& triangles = model_->triangles();
  PairCollector collector;  // the tree still holds the rest shape's boxes
  collector.pairs = &triangle_pairs_;
  triangle_pairs_.clear();
  tree_->collideTTpersistentStack(tree_->m_root, tree_->m_root, collector);
  std::vector<char> tangled(model_->num_particles(), 0);
  for (const auto& [ta, tb] : triangle_pairs_) {
    const Eigen::Vector3i& a = triangles[ta];
    const Eigen::Vector3i& b = triangles[tb];
    if (!AnEdgeCrosses(rest, a, b) && !AnEdgeCrosses(rest, b, a)) continue;
    for (int k = 0; k < 3; ++k) tangled[a[k]] = tangled[b[k]] = 1;
  }
  triangle_pairs_.clear();
  return tangled;
}

void SelfCollision::AssignOwnership() {
  // Each particle and edge belongs to the first triangle that holds it.
  const auto& triangles = model_->triangles();
  const int num_triangles = static_cast<int>(triangles.size());
  edges_ = UniqueEdges(*model_);
  owned_.assign(num_triangles, Owned{});
  std::vector<bool> vertex_taken(model_->num_particles(), false);
  for (int t = 0; t < num_triangles; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int v = triangles[t][k];
      if (!vertex_taken[v]) {
        vertex_taken[v] = true;
        owned_[t].vertices[owned_[t].num_vertices++] = v;
      }
    }
  }
  std::map<std::pair<int, int>, int> edge_owner;
  for (int t = 0; t < num_triangles; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = triangles[t][k], b = triangles[t][(k + 1) % 3];
      edge_owner.emplace(std::make_pair(std::min(a, b), std::max(a, b)), t);
    }
  }
  for (int e = 0; e < static_cast<int>(edges_.size()); ++e) {
    Owned& o = owned_[edge_owner.at(edges_[e])];
    o.edges[o.num_edges++] = e;
  }
}

void SelfCollision::BuildTree() {
  // The tree's topology comes from the rest shape (top-down, balanced); steps only refit it.
  const auto& triangles = model_->triangles();
  const int num_triangles = static_cast<int>(triangles.size());
  leaves_.assign(num_triangles, nullptr);
  for (int t = 0; t < num_triangles; ++t) {
    btVector3 lo(1e300, 1e300, 1e300), hi(-1e300, -1e300, -1e300);
    for (int k = 0; k < 3; ++k) {
      const Vec3 x = Row(model_->rest_positions(), triangles[t][k]);
      const btVector3 p(x.x(), x.y(), x.z());
      lo.setMin(p);
      hi.setMax(p);
    }
    tree_->insert(btDbvtVolume::FromMM(lo, hi),
                  reinterpret_cast<void*>(static_cast<std::intptr_t>(t)));
  }
  tree_->optimizeTopDown();
  // Nodes in pre-order; reversed, every child comes before its parent (the refit order).
  std::vector<btDbvtNode*> stack;
  if (tree_->m_root != nullptr) stack.push_back(tree_->m_root);
  while (!stack.empty()) {
    btDbvtNode* node = stack.back();
    stack.pop_back();
    if (node->isleaf()) {
      leaves_[static_cast<int>(reinterpret_cast<std::intptr_t>(node->data))] = node;
    } else {
      internal_nodes_.push_back(node);
      stack.push_back(node->childs[0]);
      stack.push_back(node->childs[1]);
    }
  }
  std::reverse(internal_nodes_.begin(), internal_nodes_.end());
}

void SelfCollision::ReserveScratch() {
  const int n = model_->num_particles();
  const std::size_t num_triangles = model_->triangles().size();
  const auto rows = static_cast<Eigen::Index>(num_triangles);
  // Typical peaks for a cloth: a few dozen overlapping pairs per triangle.
  triangle_pairs_.reserve(32 * num_triangles + 64);
  pairs_.reserve(64 * num_triangles + 64);
  proximities_.reserve(16 * num_triangles + 64);
  box_lo_.resize(n, 3);
  box_hi_.resize(n, 3);
  edge_lo_.resize(static_cast<Eigen::Index>(edges_.size()), 3);
  edge_hi_.resize(static_cast<Eigen::Index>(edges_.size()), 3);
  triangle_lo_.resize(rows, 3);
  triangle_hi_.resize(rows, 3);
  triangle_changed_.assign(num_triangles, 0);
  particle_changed_.assign(n, 0);
  path_examined_.resize(n, 3);
  tree_stack_ = std::make_unique<TreeStack>();
  tree_stack_->nodes.reserve(128);  // a walk holds about two nodes per level of the tree
  path_velocity_.resize(n, 3);
  zone_parent_.resize(n);
  zone_size_.resize(n);
  zone_mass_.resize(n);
  zone_momentum_.resize(n, 3);
  zone_state_momentum_.resize(n, 3);
}

SelfCollision::~SelfCollision() = default;

void SelfCollision::Refit(const Points& start, double h, double margin) {
  box_lo_ = start.cwiseMin(start + h * path_velocity_);
  box_hi_ = start.cwiseMax(start + h * path_velocity_);
  for (std::size_t e = 0; e < edges_.size(); ++e) {
    edge_lo_.row(e) = box_lo_.row(edges_[e].first).cwiseMin(box_lo_.row(edges_[e].second));
    edge_hi_.row(e) = box_hi_.row(edges_[e].first).cwiseMax(box_hi_.row(edges_[e].second));
  }
  const auto& triangles = model_->triangles();
  // Two leaves overlap when their boxes come within twice the fattening, so each is fattened
  // by half the margin: fattened by all of it, the proximity stage's walk also met every
  // pair 4-8 mm apart, which the primitives' own test then threw away.
  const double fat = 0.5 * margin;
  for (std::size_t t = 0; t < leaves_.size(); ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    triangle_lo_.row(t) = box_lo_.row(tri[0]).cwiseMin(box_lo_.row(tri[1])).cwiseMin(box_lo_.row(tri[2]));
    triangle_hi_.row(t) = box_hi_.row(tri[0]).cwiseMax(box_hi_.row(tri[1])).cwiseMax(box_hi_.row(tri[2]));
    leaves_[t]->volume = btDbvtVolume::FromMM(
        btVector3(triangle_lo_(t, 0) - fat, triangle_lo_(t, 1) - fat, triangle_lo_(t, 2) - fat),
        btVector3(triangle_hi_(t, 0) + fat, triangle_hi_(t, 1) + fat, triangle_hi_(t, 2) + fat));
  }
  for (btDbvtNode* node : internal_nodes_) {
    Merge(node->childs[0]->volume, node->childs[1]->volume, node->volume);
  }
}

void SelfCollision::CollectTrianglePairs(Candidates candidates) {
  triangle_pairs_.clear();
  if (candidates == Candidates::kAll) {
    PairCollector collector;
    collector.pairs = &triangle_pairs_;
    tree_->collideTTpersistentStack(tree_->m_root, tree_->m_root, collector);
    return;
  }
  // Only a changed path can meet anything new: the rest were examined on this same path.
  const auto& triangles = model_->triangles();
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    triangle_changed_[t] =
        particle_changed_[tri[0]] || particle_changed_[tri[1]] || particle_changed_[tri[2]];
  }
  ChangedPairCollector collector;
  collector.changed = &triangle_changed_;
  collector.pairs = &triangle_pairs_;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (!triangle_changed_[t]) continue;
    collector.triangle = static_cast<int>(t);
    tree_->collideTVNoStackAlloc(tree_->m_root, leaves_[t]->volume, tree_stack_->nodes, collector);
  }
}

bool SelfCollision::Overlaps(const PrimitivePair& pair, double margin) const {
  if (pair.kind == PrimitivePair::kPointTriangle) {
    return RowsOverlap(box_lo_, box_hi_, pair.a, triangle_lo_, triangle_hi_, pair.b, margin);
  }
  return RowsOverlap(edge_lo_, edge_hi_, pair.a, edge_lo_, edge_hi_, pair.b, margin);
}

bool SelfCollision::Changed(const PrimitivePair& pair) const {
  int index[4];
  PairIndices(pair, *model_, edges_, index);
  return particle_changed_[index[0]] || particle_changed_[index[1]] ||
         particle_changed_[index[2]] || particle_changed_[index[3]];
}

void SelfCollision::CollectPairs(double margin, Candidates candidates) {
  if (candidates == Candidates::kKeptAndChanged) {
    // The pairs the last collection found whose paths have not changed since: their boxes
    // are the same, so the ones still within the (smaller) margin are what a fresh search
    // would find among them.
    const auto changed_or_far = [&](const PrimitivePair& pair) {
      return Changed(pair) || !Overlaps(pair, margin);
    };
    pairs_.erase(std::remove_if(pairs_.begin(), pairs_.end(), changed_or_far), pairs_.end());
  } else {
    pairs_.clear();
  }
  CollectTrianglePairs(candidates == Candidates::kAll ? Candidates::kAll : Candidates::kChanged);
  const bool all = candidates == Candidates::kAll;
  const auto add = [&](const PrimitivePair& pair) {
    if ((all || Changed(pair)) && Overlaps(pair, margin)) pairs_.push_back(pair);
  };
  const auto& triangles = model_->triangles();
  for (const auto& [ta, tb] : triangle_pairs_) {
    if (triangle_tangled_[ta] && triangle_tangled_[tb]) continue;  // FindRestTangles
    for (int side = 0; side < 2; ++side) {
      const int own = side == 0 ? ta : tb, other = side == 0 ? tb : ta;
      const Eigen::Vector3i& tri = triangles[other];
      const Owned& o = owned_[own];
      for (int k = 0; k < o.num_vertices; ++k) {
        const int v = o.vertices[k];
        if (v == tri[0] || v == tri[1] || v == tri[2]) continue;
        add({PrimitivePair::kPointTriangle, v, other});
      }
    }
    const Owned& oa = owned_[ta];
    const Owned& ob = owned_[tb];
    for (int i = 0; i < oa.num_edges; ++i) {
      const auto& [a0, a1] = edges_[oa.edges[i]];
      for (int j = 0; j < ob.num_edges; ++j) {
        const auto& [b0, b1] = edges_[ob.edges[j]];
        if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1) continue;
        add({PrimitivePair::kEdgeEdge, oa.edges[i], ob.edges[j]});
      }
    }
  }
}

void SelfCollision::StartExamining() {
  path_examined_ = path_velocity_;
  std::fill(particle_changed_.begin(), particle_changed_.end(), 0);
}

void SelfCollision::FlagChangedPaths() {
  for (Eigen::Index i = 0; i < path_velocity_.rows(); ++i) {
    if (path_velocity_.row(i) != path_examined_.row(i)) particle_changed_[i] = 1;
  }
}

// Bridson §7.2, with two deviations (docs/collision.md): pairs are also taken when they end
// the step closer than the thickness, and the repulsion aims at the thickness by the end of
// the step (not 0.1·d/h) but moves positions only; the state velocity just loses its approach.
// Closest points and normals come from the start positions, which do not change, so they are
// found once and the Gauss-Seidel sweeps only revisit the pairs within reach.
void SelfCollision::ProximityStage(const Points& start, double h, ClothState& state,
                                   SelfCollisionReport& report) {
  const double thickness = settings_.thickness;
  proximities_.clear();
  for (const PrimitivePair& pair : pairs_) {
    int index[4];
    PairIndices(pair, *model_, edges_, index);
    Vec3 x0[4], x1[4];
    for (int k = 0; k < 4; ++k) {
      x0[k] = Row(start, index[k]);
      x1[k] = x0[k] + h * Row(path_velocity_, index[k]);
    }
    ++report.pairs_tested;
    // Near at the start, or else at the end: a point sliding faster than a triangle is wide
    // is near a triangle at the end that it was beside at the start, where its gap leans.
    const Proximity p0 = Closest(pair.kind, index, x0);
    const bool near_at_start = p0.distance < thickness;
    const Proximity p = near_at_start ? p0 : Closest(pair.kind, index, x1);
    if (p.distance >= thickness) continue;
    const Vec3 side = -Combine(path_velocity_, p.stencil);  // approaching from the normal side
    NearPair near;
    near.stencil = p.stencil;
    if (!FacingNormal(pair.kind, near_at_start ? x0 : x1, p, side, &near.normal,
                      &near.distance)) {
      continue;
    }
    if (!near_at_start) {  // the distance the step starts from, along the end's normal
      Vec3 start_gap = Vec3::Zero();
      for (int k = 0; k < 4; ++k) start_gap += p.stencil.weight[k] * x0[k];
      near.distance = std::max(start_gap.dot(near.normal), 0.0);
    }
    near.inverse_mass = InverseEffectiveMass(p.stencil, inverse_mass_);
    if (near.inverse_mass <= 0.0) continue;  // all four pinned
    near.friction = PairFriction(p.stencil);
    // Bridson's bound: stopping the approach is always allowed; pushing apart only as far
    // as the repulsion spring's impulse h·k·d goes.
    const double approach = std::max(-Combine(path_velocity_, p.stencil).dot(near.normal), 0.0);
    const double overlap = std::max(thickness - near.distance, 0.0);
    const double spring_bound = approach / near.inverse_mass + h * settings_.stiffness * overlap;
    // Alone means against the body too: with held particles as heavy as it (HeldMasses).
    double held[4];
    HeldMasses(p.stencil, near.normal, held);
    near.max_impulse = std::min(spring_bound, FullParting(approach, near.distance, h) /
                                                  InverseEffectiveMass(p.stencil, held));
    proximities_.push_back(near);
  }
  const int num_holds = static_cast<int>(holds_->size());
  hold_path_start_.resize(num_holds);
  hold_state_start_.resize(num_holds);
  hold_path_push_.assign(num_holds, 0.0);
  hold_state_push_.assign(num_holds, 0.0);
  for (int c = 0; c < num_holds; ++c) {
    const BodyHold& hold = (*holds_)[c];
    hold_path_start_[c] = Row(path_velocity_, hold.particle).dot(hold.normal);
    hold_state_start_[c] = Row(state.velocities, hold.particle).dot(hold.normal);
  }
  const int sweeps = std::max(settings_.max_iterations, 1) * kProximitySweepsPerIteration;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    int acted = 0;
    for (NearPair& near : proximities_) acted += Repel(near, h, state) ? 1 : 0;
    if (acted == 0) break;
    for (int c = 0; c < num_holds; ++c) Hold(c, state);
  }
  // Friction once, from each pair's final normal impulse: applied at every sweep's increment
  // it also counted the impulses later sweeps took back, and a patch on a sheet at μ 0.32
  // slid at a fifth of Coulomb's acceleration.
  for (const NearPair& near : proximities_) {
    ApplyFriction(path_velocity_, near.stencil, inverse_mass_, near.normal,
                  near.path_impulse * near.inverse_mass, near.friction);
    ApplyFriction(state.velocities, near.stencil, inverse_mass_, near.normal,
                  near.state_impulse * near.inverse_mass, near.friction);
    report.proximity_impulses += near.path_impulse > 0.0 || near.state_impulse > 0.0 ? 1 : 0;
  }
}

// The body behind a held particle takes whatever pushes it inward: its outward velocity
// change is accumulated and kept >= 0, in the same sweeps as the pairs', so a pair pressing
// a held layer moves the other layer instead of sharing the motion (momentum comes from the
// body, an infinite mass).
bool SelfCollision::Hold(int c, ClothState& state) {
  const BodyHold& hold = (*holds_)[c];
  const int i = hold.particle;
  if (inverse_mass_[i] <= 0.0) return false;
  const Vec3& n = hold.normal;
  const double path_push = std::max(
      hold_path_push_[c] + hold_path_start_[c] - Row(path_velocity_, i).dot(n), 0.0);
  const double state_push = std::max(
      hold_state_push_[c] + hold_state_start_[c] - Row(state.velocities, i).dot(n), 0.0);
  path_velocity_.row(i) += (path_push - hold_path_push_[c]) * n.transpose();
  state.velocities.row(i) += (state_push - hold_state_push_[c]) * n.transpose();
  const bool acted = path_push != hold_path_push_[c] || state_push != hold_state_push_[c];
  hold_path_push_[c] = path_push;
  hold_state_push_[c] = state_push;
  return acted;
}

// A held particle that a pair's impulse (along +n) would push into the body weighs as the
// body does. If that leaves the pair nothing to move, or only a particle of small weight,
// which would have to move as 1/weight (a run of the walking skirt slowed to minutes a
// frame), the pair keeps its own masses and the holds' sweeps restore the held particle.
void SelfCollision::HeldMasses(const Stencil& s, const Vec3& n, double inverse[4]) const {
  double effective = 0.0, largest_gain = 0.0;
  bool held_side[2] = {false, false};
  for (int k = 0; k < 4; ++k) {
    const int i = s.index[k];
    inverse[k] = inverse_mass_[i];
    const int c = hold_of_[i];
    if (c >= 0 && s.weight[k] * n.dot((*holds_)[c].normal) < 0.0) {
      inverse[k] = 0.0;
      held_side[s.weight[k] > 0.0 ? 0 : 1] = true;
    }
    effective += s.weight[k] * s.weight[k] * inverse[k];
    largest_gain = std::max(largest_gain, std::abs(s.weight[k]) * inverse[k]);
  }
  const bool pinched = held_side[0] && held_side[1];
  if (pinched || !(effective > 0.0) || largest_gain > kMaxHeldGain * effective) {
    for (int k = 0; k < 4; ++k) inverse[k] = inverse_mass_[s.index[k]];
  }
}

// Why a pair's impulse is also capped at what would part that pair alone: the spring's
// bound is no bound for light particles (k = 1000 N/m on particles of tens of milligrams:
// metres a step for a 2 mm overlap). Pairs of a fold that cannot all be met at once (a
// layer pressed between two others) then pile up impulses in the sweeps that cancel on the
// heavily weighted particles and throw the lightly weighted ones: a traced particle of the
// walking dress at 90 around, weighted 0.16-0.32 in its pairs, went 24 mm in one step,
// 11 mm into the knee, its partners under 10 mm. Capped, a pair alone still parts fully
// (the head-on property), and what a cluster cannot meet is left to the collision passes
// and the next step.
double SelfCollision::FullParting(double approach, double distance, double h) const {
  const double tolerance = kProximityToleranceFraction * settings_.thickness;
  return approach + (settings_.thickness + 2.0 * tolerance - distance) / h;
}

// Projected Gauss-Seidel: each pair keeps its accumulated impulse, which a later visit may
// lower again (never below zero), so the sweeps converge to the non-negative impulses that
// satisfy every pair at once instead of piling up whatever the first visits applied.
bool SelfCollision::Repel(NearPair& near, double h, ClothState& state) {
  const double thickness = settings_.thickness;
  const double tolerance = kProximityToleranceFraction * thickness;
  const Stencil& stencil = near.stencil;
  const Vec3& n = near.normal;
  // Aimed two tolerances beyond the thickness, so that a pair the sweeps leave within
  // tolerance of its target still ends the step at least the thickness apart.
  const double path_change =
      FullParting(-Combine(path_velocity_, stencil).dot(n), near.distance, h);
  const double path_impulse =
      std::clamp(near.path_impulse + path_change / near.inverse_mass, 0.0, near.max_impulse);
  const double state_change = -Combine(state.velocities, stencil).dot(n);
  const double state_impulse =
      std::max(near.state_impulse + state_change / near.inverse_mass, 0.0);
  const double path_delta = (path_impulse - near.path_impulse) * near.inverse_mass;
  const double state_delta = (state_impulse - near.state_impulse) * near.inverse_mass;
  const bool path_acts = h * std::abs(path_delta) > tolerance;
  const bool state_acts = h * std::abs(state_delta) > tolerance;
  if (path_acts) {
    ApplyRelativeChange(path_velocity_, stencil, inverse_mass_, n, path_delta);
    near.path_impulse = path_impulse;
  }
  if (state_acts) {
    ApplyRelativeChange(state.velocities, stencil, inverse_mass_, n, state_delta);
    near.state_impulse = state_impulse;
  }
  return path_acts || state_acts;
}

// The stencil's positive weights are one side of the gap (the point, or edge A's point),
// its negative weights the other; each side's coefficient is its particles' weighted mean.
double SelfCollision::PairFriction(const Stencil& stencil) const {
  if (settings_.particle_friction.empty()) return settings_.friction;
  double side[2] = {0.0, 0.0}, weight[2] = {0.0, 0.0};
  for (int k = 0; k < 4; ++k) {
    const double own = settings_.particle_friction[stencil.index[k]];
    const int s = stencil.weight[k] > 0.0 ? 0 : 1;
    const double w = std::abs(stencil.weight[k]);
    side[s] += w * (own < 0.0 ? settings_.friction : own);
    weight[s] += w;
  }
  if (weight[0] <= 0.0 || weight[1] <= 0.0) return settings_.friction;
  return MixFriction(side[0] / weight[0], side[1] / weight[1]);
}

// Bridson §6 and §7.3: the earliest coplanarity time in the step at which the primitives
// also touch is a collision; an inelastic impulse along the normal at that time stops their
// approach. With merge_zones, collisions only join their particles' impact zones.
int SelfCollision::CollisionPass(const Points& start, double h, ClothState& state,
                                 bool merge_zones, Candidates candidates,
                                 SelfCollisionReport& report) {
  // Continuous detection needs no thickness: only boxes that touch along the path matter.
  const double tolerance = kCollisionToleranceFraction * settings_.thickness;
  FlagChangedPaths();
  Refit(start, h, tolerance);
  CollectPairs(tolerance, candidates);
  StartExamining();
  ++report.collision_passes;
  int found = 0;
  for (const PrimitivePair& pair : pairs_) {
    int index[4];
    PairIndices(pair, *model_, edges_, index);
    if (merge_zones) {
      const int zone = Find(zone_parent_, index[0]);
      bool same = true;
      for (int k = 1; k < 4; ++k) same = same && Find(zone_parent_, index[k]) == zone;
      if (same) continue;  // a zone moves rigidly: its own particles cannot collide
    }
    ++report.pairs_tested;
    Vec3 x0[4], dx[4];
    for (int k = 0; k < 4; ++k) {
      x0[k] = Row(start, index[k]);
      dx[k] = h * Row(path_velocity_, index[k]);
    }
    double coefficients[4], roots[6];
    CoplanarityCubic(pair.kind, x0, dx, coefficients);
    const int num_roots = CubicRootsInUnitInterval(coefficients[0], coefficients[1],
                                                   coefficients[2], coefficients[3], roots);
    for (int r = 0; r < num_roots; ++r) {
      Vec3 xt[4];
      for (int k = 0; k < 4; ++k) xt[k] = x0[k] + roots[r] * dx[k];
      const Proximity pt = Closest(pair.kind, index, xt);
      if (pt.distance > tolerance) continue;
      // The normal at the collision, pointing to the side the first primitive started on.
      Vec3 n = PlaneNormal(pair.kind, xt);
      if (n.norm() <= 1e-30) n = pt.gap;
      if (n.norm() <= 1e-30) continue;
      n.normalize();
      Vec3 start_gap = Vec3::Zero();
      for (int k = 0; k < 4; ++k) start_gap += pt.stencil.weight[k] * x0[k];
      const double start_side = start_gap.dot(n);
      const double normal_velocity = Combine(path_velocity_, pt.stencil).dot(n);
      if (std::abs(start_side) > kMotionTolerance) {
        if (start_side < 0.0) n = -n;
      } else if (normal_velocity > 0.0) {
        n = -n;
      }
      const double approach = -Combine(path_velocity_, pt.stencil).dot(n);
      if (h * approach <= kMotionTolerance) continue;
      ++found;
      for (int k = 0; k < 4; ++k) particle_changed_[index[k]] = 1;  // examined again next pass
      if (merge_zones) {
        for (int k = 1; k < 4; ++k) {
          zone_parent_[Find(zone_parent_, index[k])] = Find(zone_parent_, index[0]);
        }
      } else {
        double inverse[4];
        HeldMasses(pt.stencil, n, inverse);
        ApplyRelativeChange(path_velocity_, pt.stencil, inverse, n, approach);
        const double state_approach = -Combine(state.velocities, pt.stencil).dot(n);
        if (state_approach > 0.0) {
          ApplyRelativeChange(state.velocities, pt.stencil, inverse, n, state_approach);
        }
        ++report.collision_impulses;
      }
      break;  // the earliest collision of this pair is the one that counts
    }
  }
  return found;
}

// Provot 1997 / Bridson §7.4 "rigid impact zones", simplified to translation: colliding
// particles are merged into zones and each zone moves with its momentum-weighted mean
// velocity, so nothing inside a zone moves relative to anything else (linear momentum is
// kept; the zone's spin is lost, an inelastic choice). Zones grow until nothing collides.
void SelfCollision::ImpactZones(const Points& start, double h, ClothState& state,
                                Candidates candidates, SelfCollisionReport& report) {
  const int n = model_->num_particles();
  for (int i = 0; i < n; ++i) zone_parent_[i] = i;
  const double pinned_weight = kPinnedWeightFactor * model_->total_mass();
  int found = CollisionPass(start, h, state, true, candidates, report);
  for (int pass = 0; found > 0 && pass < kMaxZonePasses; ++pass) {
    zone_mass_.setZero();
    zone_momentum_.setZero();
    zone_state_momentum_.setZero();
    std::fill(zone_size_.begin(), zone_size_.end(), 0);
    for (int i = 0; i < n; ++i) {
      const int z = Find(zone_parent_, i);
      ++zone_size_[z];
      // Held particles weigh as pins, so a zone holding one moves with the body; unlike
      // pins they move with the zone, so a zone of several held particles still moves rigidly.
      const bool held = hold_of_[i] >= 0;
      const double weight =
          inverse_mass_[i] > 0.0 && !held ? 1.0 / inverse_mass_[i] : pinned_weight;
      zone_mass_[z] += weight;
      zone_momentum_.row(z) += weight * path_velocity_.row(i);
      zone_state_momentum_.row(z) += weight * state.velocities.row(i);
    }
    for (int i = 0; i < n; ++i) {
      const int z = Find(zone_parent_, i);
      if (inverse_mass_[i] == 0.0) continue;  // pins keep their own velocity exactly
      if (zone_size_[z] == 1) continue;
      path_velocity_.row(i) = zone_momentum_.row(z) / zone_mass_[z];
      state.velocities.row(i) = zone_state_momentum_.row(z) / zone_mass_[z];
    }
    found = CollisionPass(start, h, state, true, Candidates::kChanged, report);
  }
  report.remaining_collisions = found;
  std::fill(zone_size_.begin(), zone_size_.end(), 0);
  for (int i = 0; i < n; ++i) ++zone_size_[Find(zone_parent_, i)];
  for (int i = 0; i < n; ++i) report.zone_particles += zone_size_[Find(zone_parent_, i)] > 1 ? 1 : 0;
}

SelfCollisionReport SelfCollision::Resolve(const Points& start_positions, double h,
                                           ClothState& state,
                                           const std::vector<BodyHold>& holds) {
  return ResolvePath(start_positions, h, state, holds, PathMode::kWhole);
}

SelfCollisionReport SelfCollision::ResolveMove(const Points& start_positions, double h,
                                               ClothState& state,
                                               const std::vector<BodyHold>& holds) {
  return ResolvePath(start_positions, h, state, holds, PathMode::kMoving);
}

SelfCollisionReport SelfCollision::ResolveCrossings(const Points& start_positions, double h,
                                                    ClothState& state,
                                                    const std::vector<BodyHold>& holds) {
  return ResolvePath(start_positions, h, state, holds, PathMode::kMovingCrossings);
}

SelfCollisionReport SelfCollision::ResolvePath(const Points& start_positions, double h,
                                               ClothState& state,
                                               const std::vector<BodyHold>& holds,
                                               PathMode mode) {
  SelfCollisionReport report;
  const bool moving_only = mode != PathMode::kWhole;
  const Eigen::Index n = model_->num_particles();
  const auto bad_hold = [n](const BodyHold& hold) {
    return hold.particle < 0 || hold.particle >= n || !hold.normal.allFinite();
  };
  if (start_positions.rows() != n || state.positions.rows() != n ||
      state.velocities.rows() != n || !(h > 0.0) || !std::isfinite(h) ||
      !start_positions.allFinite() || !state.positions.allFinite() ||
      !state.velocities.allFinite() || std::any_of(holds.begin(), holds.end(), bad_hold)) {
    report.skipped = true;
    return report;
  }
  holds_ = &holds;
  hold_of_.assign(n, -1);
  for (int c = 0; c < static_cast<int>(holds.size()); ++c) hold_of_[holds[c].particle] = c;
  if (leaves_.empty()) return report;
  path_velocity_ = (state.positions - start_positions) / h;
  Refit(start_positions, h, settings_.thickness);
  if (moving_only) {  // flags the moving particles: a pair at rest keeps its distance
    path_examined_.setZero();
    std::fill(particle_changed_.begin(), particle_changed_.end(), 0);
    FlagChangedPaths();
  }
  CollectPairs(settings_.thickness, moving_only ? Candidates::kChanged : Candidates::kAll);
  StartExamining();
  if (mode != PathMode::kMovingCrossings) ProximityStage(start_positions, h, state, report);
  // The first pass also examines the pairs collected above that the proximity stage (when
  // it ran) left alone; later passes only the pairs whose paths the last pass changed or
  // found colliding.
  Candidates candidates = Candidates::kKeptAndChanged;
  int found = 1;
  for (int pass = 0; found > 0 && pass < settings_.max_iterations; ++pass) {
    found = CollisionPass(start_positions, h, state, false, candidates, report);
    candidates = Candidates::kChanged;
  }
  if (found > 0) ImpactZones(start_positions, h, state, candidates, report);
  state.positions = start_positions + h * path_velocity_;
  return report;
}

namespace {

/// The triangles whose boxes a crossing-edge query's box overlaps.
struct TriangleCollector : btDbvt::ICollide {
  std::vector<int>* triangles = nullptr;
  void Process(const btDbvtNode* leaf) { triangles->push_back(leaf->dataAsInt); }
};

btVector3 ToBt(const Vec3& v) { return btVector3(v.x(), v.y(), v.z()); }

}  // namespace

// Why a tree: the brute force over every edge and triangle took 0.5 s on a 3,000-particle
// suit, and garment runs count every frame. An edge can only cross a triangle whose box its
// own box overlaps, so the tree's cull changes no answer. The triangles' boxes are grown by
// 10 µm so that Bullet's single-precision corners cannot shrink a box past a crossing.
int CountCrossingEdges(const ClothModel& model, const Points& positions) {
  constexpr double kPad = 1e-5;  // m
  const auto edges = UniqueEdges(model);
  const auto& triangles = model.triangles();
  btDbvt tree;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Vec3 a = Row(positions, triangles[t][0]), b = Row(positions, triangles[t][1]),
               c = Row(positions, triangles[t][2]);
    tree.insert(btDbvtVolume::FromMM(ToBt(Vec3(a.cwiseMin(b).cwiseMin(c).array() - kPad)),
                                     ToBt(Vec3(a.cwiseMax(b).cwiseMax(c).array() + kPad))),
                reinterpret_cast<void*>(static_cast<std::intptr_t>(t)));
  }
  std::vector<int> candidates;
  TriangleCollector collect;
  collect.triangles = &candidates;
  int count = 0;
  for (const auto& [a, b] : edges) {
    const Vec3 p = Row(positions, a), q = Row(positions, b);
    candidates.clear();
    tree.collideTV(tree.m_root, btDbvtVolume::FromMM(ToBt(p.cwiseMin(q)), ToBt(p.cwiseMax(q))),
                   collect);
    std::sort(candidates.begin(), candidates.end());  // the brute force's order: same answer
    for (int index : candidates) {
      const Eigen::Vector3i& t = triangles[index];
      if (t[0] == a || t[1] == a || t[2] == a || t[0] == b || t[1] == b || t[2] == b) continue;
      if (SegmentCrossesTriangle(p, q, Row(positions, t[0]), Row(positions, t[1]),
                                 Row(positions, t[2]))) {
        ++count;
        break;  // count the edge once
      }
    }
  }
  return count;
}

}  // namespace costume::sim
