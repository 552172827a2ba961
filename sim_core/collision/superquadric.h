#pragma once
/// @file
/// Superquadrics (Barr 1981) and their least-squares fit to points after Solina & Bajcsy 1990
/// ("Recovery of parametric models from range images", IEEE PAMI 12(2)): the shape of the fast
/// collision method of paper §4 (DESIGN.md "Collision"), one per H-Anim body segment.
///
/// In its own frame a superquadric is centred at the origin with its axes along x, y, z:
///   F(p) = ((|x|/a1)^(2/e2) + (|y|/a2)^(2/e2))^(e2/e1) + (|z|/a3)^(2/e1),
/// F < 1 inside, F = 1 on the surface, F > 1 outside. e1 shapes the profile along z (the
/// "latitude" exponent), e2 the cross-section in the xy plane; 1 gives round, 0.1 nearly
/// square, 2 diamond-shaped profiles. F is homogeneous along rays from the centre:
/// F(s·p) = s^(2/e1)·F(p) for s > 0, which makes the radial quantities below closed forms.

#include <Eigen/Geometry>
#include <string>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// Bounds of the shape exponents e1, e2 [-]: below 0.1 the powers 2/e overflow for points a
/// few sizes away; above 2 the surface is no longer convex.
inline constexpr double kMinSuperquadricExponent = 0.1;
inline constexpr double kMaxSuperquadricExponent = 2.0;

struct Superquadric {
  /// Half sizes along the superquadric's x, y, z axes [m] > 0.
  double a1 = 1.0;
  double a2 = 1.0;
  double a3 = 1.0;
  /// Shape exponents [-] in [kMinSuperquadricExponent, kMaxSuperquadricExponent]: e1 along
  /// z, e2 in the xy cross-section.
  double e1 = 1.0;
  double e2 = 1.0;
  /// The superquadric's frame relative to the frame it is attached to (its body segment's
  /// joint frame): maps superquadric coordinates to joint coordinates [m].
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
};

/// Throws InputError naming `name`, the field, its value and the allowed range unless the
/// sizes are finite and > 0, the exponents in [0.1, 2] and the frame rigid and finite.
void ValidateSuperquadric(const Superquadric& superquadric, const std::string& name);

/// The inside-outside function F at `p`, given in the superquadric's own frame [m] (not its
/// parent's: apply superquadric.frame.inverse() first). F(0) = 0. Never throws.
double InsideOutside(const Superquadric& superquadric, const Eigen::Vector3d& p);

/// ∂F/∂p at `p` (superquadric frame) [1/m]. Along a ray from the centre the gradient keeps
/// its direction, so it is the surface normal direction of the radial surface point. Zero at
/// the centre. Never throws.
Eigen::Vector3d InsideOutsideGradient(const Superquadric& superquadric, const Eigen::Vector3d& p);

/// The point of the surface on the ray from the centre through `p` (superquadric frame):
/// p·F(p)^(−e1/2), so its distance from the centre is r_s = |p|·F^(−e1/2) [m].
/// Precondition: p ≠ 0. Never throws.
Eigen::Vector3d RadialSurfacePoint(const Superquadric& superquadric, const Eigen::Vector3d& p);

/// Signed distance of `p` from the surface along the ray from the centre, |p| − r_s [m]:
/// > 0 outside, < 0 inside; −min(a1, a2, a3) at the centre, which has no ray.
/// An estimate of the Euclidean distance: equal to it on a sphere, larger elsewhere (by
/// 1/cos of the angle between the ray and the surface normal, near the surface).
double RadialDistance(const Superquadric& superquadric, const Eigen::Vector3d& p);

/// The surface point for the parametric angles eta ∈ [−π/2, π/2] (latitude) and omega ∈
/// [−π, π] (longitude), superquadric frame [m]:
///   x = a1·c(eta)^e1·c(omega)^e2,  y = a2·c(eta)^e1·s(omega)^e2,  z = a3·s(eta)^e1,
/// with c(t)^e = sign(cos t)·|cos t|^e and s(t)^e likewise. Never throws.
Eigen::Vector3d ParametricSurfacePoint(const Superquadric& superquadric, double eta, double omega);

/// The parametric angles (eta, omega) of the radial surface point of `p` (superquadric
/// frame): the inverse of ParametricSurfacePoint along rays from the centre, computed
/// without projecting (both angles are ratios of powers that are invariant under p → s·p).
/// Returns (0, 0) at the centre. Never throws.
Eigen::Vector2d ParametricAngles(const Superquadric& superquadric, const Eigen::Vector3d& p);

/// Options of FitSuperquadric.
struct SuperquadricFitOptions {
  /// Levenberg–Marquardt iterations at most [-] > 0.
  int max_iterations = 200;
  /// At most this many points enter the fit (an even stride through the input) [-] > 0:
  /// a dense skin adds time, not accuracy.
  int max_points = 4000;
  /// The fit stops when an iteration lowers the cost by less than this fraction of it [-].
  double relative_tolerance = 1e-8;
};

/// A fitted superquadric and how well it fits.
struct SuperquadricFit {
  /// frame maps superquadric coordinates to the coordinates the points were given in.
  Superquadric superquadric;
  /// Root mean square of RadialDistance over all input points [m]: the residual of the fit.
  double rms_radial_distance = 0.0;
  /// Largest |RadialDistance| over all input points [m].
  double max_radial_distance = 0.0;
  /// Σ residual² of the fit's cost (FitSuperquadric) at the start and the end [m³].
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int num_iterations = 0;
};

/// Derivatives of a point's fit residual (FitSuperquadric) by a1, a2, a3, e1, e2, the
/// frame's translation (3) and a rotation increment ω applied as R ← R·exp([ω]×) (3).
using SuperquadricFitGradient = Eigen::Matrix<double, 11, 1>;

/// The residual FitSuperquadric gives the point whose superquadric coordinates are `p`:
/// sqrt(a1·a2·a3)·(F(p)^e1 − 1) [m^1.5], and, unless `gradient` is null, its derivatives in
/// closed form, holding the point fixed in the superquadric's parent frame (0 at the centre,
/// where F has no direction). Never throws.
double SuperquadricFitResidual(const Superquadric& superquadric, const Eigen::Vector3d& p,
                               SuperquadricFitGradient* gradient = nullptr);

/// Fits a superquadric to `points` (n×3) [m] after Solina & Bajcsy 1990: minimises
///   Σ_i (sqrt(a1·a2·a3)·(F(p_i)^e1 − 1))² + Σ_ends (w·max(0, reach beyond the ends))²
/// over the sizes, the exponents and the pose (position and rotation, 11 parameters) by
/// Levenberg–Marquardt, the points' Jacobian in closed form (SuperquadricFitResidual), the
/// ends' by forward differences. The rotation is updated multiplicatively
/// (R ← R·exp([δω]×)) so it needs no angle parameterisation. The exponents
/// are kept in [0.1, 2] and the sizes above 1e-4·(the points' extent) by projection, a
/// parameter on its bound whose descent direction points out of the box being frozen for
/// that iteration. Start: the points' centroid and principal axes (largest spread → z,
/// second → x), sizes the half extents along those axes, e1 = e2 = 1 (an ellipsoid).
/// The factor sqrt(a1·a2·a3) is Solina's: it removes the bias of F^e1 towards large shapes
/// and makes the cost prefer the smallest superquadric through the points. The second sum is
/// ours: along each of its axes the superquadric may reach 10 % of the points' half extent
/// beyond their last point (in its own frame) before the reach costs, w times the excess over
/// the half extent, each end as much as all points with that residual. An open tube of
/// points (a limb's skin) otherwise leaves the length free, and a tapering one is fitted best
/// by the wide half of a superquadric twice its length (docs/collision.md).
/// `name` names the point set in error messages. Throws InputError if there are fewer than
/// 11 points, a point is not finite, or all points coincide.
SuperquadricFit FitSuperquadric(const Points& points, const std::string& name,
                                const SuperquadricFitOptions& options = {});

}  // namespace costume::sim
