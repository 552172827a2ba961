#include "sim_core/collision/superquadric.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

/// sign(t)·|t|^e: the signed power of the parametric form.
double SignedPower(double t, double e) { return std::copysign(std::pow(std::abs(t), e), t); }

/// The xy part of F before its outer power: (|x|/a1)^(2/e2) + (|y|/a2)^(2/e2).
double CrossSection(const Superquadric& s, const Eigen::Vector3d& p) {
  return std::pow(std::abs(p.x()) / s.a1, 2.0 / s.e2) +
         std::pow(std::abs(p.y()) / s.a2, 2.0 / s.e2);
}

}  // namespace

void ValidateSuperquadric(const Superquadric& superquadric, const std::string& name) {
  RequirePositive(name + ".a1", superquadric.a1, "m");
  RequirePositive(name + ".a2", superquadric.a2, "m");
  RequirePositive(name + ".a3", superquadric.a3, "m");
  RequireInRange(name + ".e1", superquadric.e1, kMinSuperquadricExponent, kMaxSuperquadricExponent,
                 "");
  RequireInRange(name + ".e2", superquadric.e2, kMinSuperquadricExponent, kMaxSuperquadricExponent,
                 "");
  const Eigen::Matrix3d r = superquadric.frame.linear();
  if (!superquadric.frame.matrix().allFinite() ||
      !(r.transpose() * r).isApprox(Eigen::Matrix3d::Identity(), 1e-9) || r.determinant() < 0) {
    throw InputError(name +
                     ".frame: not a finite rigid transform (allowed: rotation + "
                     "translation)");
  }
}

double InsideOutside(const Superquadric& s, const Eigen::Vector3d& p) {
  return std::pow(CrossSection(s, p), s.e2 / s.e1) + std::pow(std::abs(p.z()) / s.a3, 2.0 / s.e1);
}

Eigen::Vector3d InsideOutsideGradient(const Superquadric& s, const Eigen::Vector3d& p) {
  // ∂F/∂x = (2/e1)·u^(e2/e1 − 1)·(|x|/a1)^(2/e2 − 1)·sign(x)/a1 with u the cross-section;
  // at u = 0 the product tends to 0 along every path (2/e1 − 1 >= 0), so take 0 there.
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
  const double u = CrossSection(s, p);
  if (u > 0.0) {
    const double outer = (2.0 / s.e1) * std::pow(u, s.e2 / s.e1 - 1.0);
    gradient.x() = outer * SignedPower(p.x() / s.a1, 2.0 / s.e2 - 1.0) / s.a1;
    gradient.y() = outer * SignedPower(p.y() / s.a2, 2.0 / s.e2 - 1.0) / s.a2;
  }
  gradient.z() = (2.0 / s.e1) * SignedPower(p.z() / s.a3, 2.0 / s.e1 - 1.0) / s.a3;
  return gradient;
}

Eigen::Vector3d RadialSurfacePoint(const Superquadric& s, const Eigen::Vector3d& p) {
  return p * std::pow(InsideOutside(s, p), -0.5 * s.e1);
}

double RadialDistance(const Superquadric& s, const Eigen::Vector3d& p) {
  const double length = p.norm();
  if (length == 0.0) return -std::min({s.a1, s.a2, s.a3});
  // Evaluated on the unit direction so that F stays well scaled far from the surface.
  const double surface = std::pow(InsideOutside(s, p / length), -0.5 * s.e1);
  return length - surface;
}

Eigen::Vector3d ParametricSurfacePoint(const Superquadric& s, double eta, double omega) {
  const double ce = SignedPower(std::cos(eta), s.e1);
  return {s.a1 * ce * SignedPower(std::cos(omega), s.e2),
          s.a2 * ce * SignedPower(std::sin(omega), s.e2), s.a3 * SignedPower(std::sin(eta), s.e1)};
}

Eigen::Vector2d ParametricAngles(const Superquadric& s, const Eigen::Vector3d& p) {
  // On the surface sign(x)|x/a1|^(1/e2) = |cos eta|^(e1/e2)·cos omega (and sin for y), and
  // sign(z)|z/a3|^(1/e1) = sin eta, u^(e2/(2 e1)) = |cos eta|; off the surface every term
  // scales by s^(1/e2) resp. s^(1/e1), which the ratios cancel.
  const double eta = std::atan2(SignedPower(p.z() / s.a3, 1.0 / s.e1),
                                std::pow(CrossSection(s, p), 0.5 * s.e2 / s.e1));
  const double omega =
      std::atan2(SignedPower(p.y() / s.a2, 1.0 / s.e2), SignedPower(p.x() / s.a1, 1.0 / s.e2));
  return {eta, omega};
}

namespace {

/// x·ln x, continued by its limit 0 at x = 0.
double XLogX(double x) { return x > 0.0 ? x * std::log(x) : 0.0; }

}  // namespace

double SuperquadricFitResidual(const Superquadric& s, const Eigen::Vector3d& p,
                               SuperquadricFitGradient* gradient) {
  // F = V + Z with V = U^(e2/e1), U = X + Y, X = (|x|/a1)^(2/e2), Y = (|y|/a2)^(2/e2),
  // Z = (|z|/a3)^(2/e1); G = F^e1 and the residual is w·(G − 1), w = sqrt(a1 a2 a3). Each
  // power b^(c/e) has ∂/∂e = −(1/e)·b^(c/e)·ln b^(c/e), and ∂/∂b = (c/e)·b^(c/e)/b.
  const double x = std::pow(std::abs(p.x()) / s.a1, 2.0 / s.e2);
  const double y = std::pow(std::abs(p.y()) / s.a2, 2.0 / s.e2);
  const double z = std::pow(std::abs(p.z()) / s.a3, 2.0 / s.e1);
  const double u = x + y;
  const double v = u > 0.0 ? std::pow(u, s.e2 / s.e1) : 0.0;
  const double f = v + z;
  const double g = std::pow(f, s.e1);
  const double w = std::sqrt(s.a1 * s.a2 * s.a3);
  const double residual = w * (g - 1.0);
  if (gradient == nullptr) return residual;
  gradient->setZero();
  if (!(f > 0.0)) return residual;  // the centre: no direction to move it by
  const double dg_df = s.e1 * g / f;
  const double df_du = u > 0.0 ? (s.e2 / s.e1) * v / u : 0.0;
  const Eigen::Vector3d dg_dp(
      p.x() != 0.0 ? dg_df * df_du * (2.0 / s.e2) * x / p.x() : 0.0,
      p.y() != 0.0 ? dg_df * df_du * (2.0 / s.e2) * y / p.y() : 0.0,
      p.z() != 0.0 ? dg_df * (2.0 / s.e1) * z / p.z() : 0.0);
  const double dg_da[3] = {-dg_df * df_du * (2.0 / s.e2) * x / s.a1,
                           -dg_df * df_du * (2.0 / s.e2) * y / s.a2,
                           -dg_df * (2.0 / s.e1) * z / s.a3};
  const double a[3] = {s.a1, s.a2, s.a3};
  for (int k = 0; k < 3; ++k) (*gradient)[k] = w * dg_da[k] + residual / (2.0 * a[k]);
  const double df_de1 = -(XLogX(v) + XLogX(z)) / s.e1;
  (*gradient)[3] = w * (g * std::log(f) + dg_df * df_de1);
  const double df_de2 = u > 0.0 ? (v / s.e1) * (std::log(u) - (XLogX(x) + XLogX(y)) / u) : 0.0;
  (*gradient)[4] = w * dg_df * df_de2;
  // p = Rᵀ(q − t) for the point q in the parent's frame: ∂p/∂t = −Rᵀ. An increment ω,
  // R ← R·exp([ω]×), moves p to p + p × ω.
  gradient->segment<3>(5) = -w * (s.frame.linear() * dg_dp);
  gradient->segment<3>(8) = w * dg_dp.cross(p);
  return residual;
}

// ---- fitting ------------------------------------------------------------------------------
namespace {

constexpr int kNumParameters = 11;  // a1 a2 a3 e1 e2 | translation (3) | rotation increment (3)
constexpr int kNumEndResiduals = 6;  // per axis, the + and the − end
using ParameterVector = Eigen::Matrix<double, kNumParameters, 1>;
using NormalMatrix = Eigen::Matrix<double, kNumParameters, kNumParameters>;

/// The fit's unknowns; the rotation is kept as a matrix and changed by increments.
struct FitState {
  Eigen::Vector3d a;
  Eigen::Vector2d e;
  Eigen::Vector3d translation;
  Eigen::Matrix3d rotation;
};

struct Bounds {
  double min_size = 0.0;
};

double Clamp(double v, double lo, double hi) { return std::min(std::max(v, lo), hi); }

/// The state moved by `delta` and projected onto the bounds.
FitState Apply(const FitState& state, const ParameterVector& delta, const Bounds& bounds) {
  FitState out = state;
  for (int k = 0; k < 3; ++k) out.a[k] = std::max(state.a[k] + delta[k], bounds.min_size);
  for (int k = 0; k < 2; ++k) {
    out.e[k] = Clamp(state.e[k] + delta[3 + k], kMinSuperquadricExponent, kMaxSuperquadricExponent);
  }
  out.translation = state.translation + delta.segment<3>(5);
  const Eigen::Vector3d w = delta.segment<3>(8);
  const double angle = w.norm();
  if (angle > 0.0) {
    out.rotation = state.rotation * Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  }
  return out;
}

Superquadric ToSuperquadric(const FitState& state) {
  Superquadric s;
  s.a1 = state.a[0];
  s.a2 = state.a[1];
  s.a3 = state.a[2];
  s.e1 = state.e[0];
  s.e2 = state.e[1];
  s.frame.linear() = state.rotation;
  s.frame.translation() = state.translation;
  return s;
}

/// How far a superquadric may reach beyond its points' extent along each of its axes, as
/// a fraction of their half extent [-].
constexpr double kEndSlack = 0.1;

/// Weight of an end's reach beyond the slack, per unit of the half extent, against a point's
/// residual [-].
constexpr double kEndWeight = 10.0;

/// The ends' residuals, the last kNumEndResiduals of `residuals` (Residuals); `weight` is
/// the points' sqrt(a1 a2 a3).
void EndResiduals(const FitState& state, const Points& points, double weight,
                  Eigen::VectorXd& residuals) {
  const Eigen::Matrix3d rt = state.rotation.transpose();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  const Eigen::Index n = points.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d local = rt * (points.row(i).transpose() - state.translation);
    lo = lo.cwiseMin(local);
    hi = hi.cwiseMax(local);
  }
  // Each end weighs as much as all points together would with residuals of kEndWeight times
  // the end's relative excess.
  const double end_weight = kEndWeight * weight * std::sqrt(static_cast<double>(n));
  for (int k = 0; k < 3; ++k) {
    const double half = std::max(0.5 * (hi[k] - lo[k]), 1e-12);
    const double limit = kEndSlack * half;
    residuals[n + 2 * k] = end_weight * std::max(0.0, state.a[k] - hi[k] - limit) / half;
    residuals[n + 2 * k + 1] = end_weight * std::max(0.0, state.a[k] + lo[k] - limit) / half;
  }
}

/// Residuals of the fit: per point the Solina–Bajcsy residual sqrt(a1 a2 a3)·(F^e1 − 1),
/// then per axis and end how far the superquadric reaches beyond the points' extent along
/// its axis plus the slack (kNumEndResiduals). The points of a limb's skin form an open
/// tube, which says nothing of where the superquadric ends: without the ends' residuals a
/// tapering limb is fitted best by the wide half of an ellipsoid twice its length, centred
/// at its thick end (MakeHuman's thighs and forearms were fitted so, their other halves
/// through the pelvis and the upper arm), whose centre then sees the skin of the body
/// around it, not the limb's (docs/collision.md, "The fit of an open tube").
void Residuals(const FitState& state, const Points& points, Eigen::VectorXd& residuals) {
  const Superquadric s = ToSuperquadric(state);
  const Eigen::Matrix3d rt = state.rotation.transpose();
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    residuals[i] =
        SuperquadricFitResidual(s, rt * (points.row(i).transpose() - state.translation));
  }
  EndResiduals(state, points, std::sqrt(s.a1 * s.a2 * s.a3), residuals);
}

/// The Jacobian of the residuals with respect to the increment parameters: the points' rows
/// in closed form (SuperquadricFitResidual), the ends' by forward differences. The ends
/// depend on the points only through their extremes, which take no power, so their eleven
/// differences cost little. The points' differences took eleven evaluations of F (five
/// powers each) per point and iteration: most of a superquadric collider's construction.
void Jacobian(const FitState& state, const Points& points, double scale, const Bounds& bounds,
              Eigen::MatrixXd& jacobian, Eigen::VectorXd& scratch) {
  const Superquadric s = ToSuperquadric(state);
  const Eigen::Matrix3d rt = state.rotation.transpose();
  const Eigen::Index n = points.rows();
  SuperquadricFitGradient gradient;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d local = rt * (points.row(i).transpose() - state.translation);
    SuperquadricFitResidual(s, local, &gradient);
    jacobian.row(i) = gradient.transpose();
  }
  const double weight = std::sqrt(s.a1 * s.a2 * s.a3);
  EndResiduals(state, points, weight, scratch);
  const Eigen::Matrix<double, kNumEndResiduals, 1> ends = scratch.tail<kNumEndResiduals>();
  for (int k = 0; k < kNumParameters; ++k) {
    const bool length = k < 3 || (k >= 5 && k < 8);
    double step = length ? 1e-7 * scale : 1e-7;
    // Step away from a bound so the difference sees the function, not the clamp.
    if (k >= 3 && k < 5 && state.e[k - 3] + step > kMaxSuperquadricExponent) step = -step;
    ParameterVector delta = ParameterVector::Zero();
    delta[k] = step;
    const FitState moved = Apply(state, delta, bounds);
    EndResiduals(moved, points, std::sqrt(moved.a.prod()), scratch);
    jacobian.block<kNumEndResiduals, 1>(n, k) = (scratch.tail<kNumEndResiduals>() - ends) / step;
  }
}

/// The initial guess: centroid and principal axes, largest spread along z, then x.
FitState InitialGuess(const Points& points, double& extent) {
  const Eigen::RowVector3d centroid = points.colwise().mean();
  const Points centred = points.rowwise() - centroid;
  const Eigen::Matrix3d covariance = centred.transpose() * centred / double(points.rows());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
  FitState state;
  const Eigen::Vector3d z = eigen.eigenvectors().col(2);  // eigenvalues ascend
  const Eigen::Vector3d x = eigen.eigenvectors().col(1);
  state.rotation.col(0) = x;
  state.rotation.col(1) = z.cross(x);
  state.rotation.col(2) = z;
  const Points local = centred * state.rotation;  // rows: Rᵀ(p − c)
  const Eigen::RowVector3d lo = local.colwise().minCoeff();
  const Eigen::RowVector3d hi = local.colwise().maxCoeff();
  state.a = 0.5 * (hi - lo).transpose();
  extent = state.a.maxCoeff();
  state.translation = centroid.transpose() + state.rotation * (0.5 * (hi + lo)).transpose();
  state.e = Eigen::Vector2d::Ones();
  return state;
}

/// Points taken at an even stride so that at most `max_points` remain.
Points Subsample(const Points& points, int max_points) {
  if (points.rows() <= max_points) return points;
  Points out(max_points, 3);
  for (int i = 0; i < max_points; ++i) {
    out.row(i) = points.row(Eigen::Index(double(i) * double(points.rows()) / max_points));
  }
  return out;
}

/// Freezes parameters sitting on a bound whose descent direction leaves the box.
void FreezeActiveBounds(const FitState& state, const Bounds& bounds, NormalMatrix& normal,
                        ParameterVector& gradient) {
  for (int k = 0; k < 5; ++k) {
    const double value = k < 3 ? state.a[k] : state.e[k - 3];
    const double lo = k < 3 ? bounds.min_size : kMinSuperquadricExponent;
    const double hi = k < 3 ? INFINITY : kMaxSuperquadricExponent;
    const bool pushed_low = value <= lo * (1.0 + 1e-12) && gradient[k] > 0.0;
    const bool pushed_high = value >= hi * (1.0 - 1e-12) && gradient[k] < 0.0;
    if (!pushed_low && !pushed_high) continue;
    normal.row(k).setZero();
    normal.col(k).setZero();
    normal(k, k) = 1.0;
    gradient[k] = 0.0;
  }
}

}  // namespace

SuperquadricFit FitSuperquadric(const Points& all_points, const std::string& name,
                                const SuperquadricFitOptions& options) {
  if (all_points.rows() < kNumParameters) {
    throw InputError(name + ": " + std::to_string(all_points.rows()) +
                     " points to fit a superquadric (allowed: >= 11)");
  }
  if (!all_points.allFinite()) throw InputError(name + ": non-finite point (allowed: finite)");
  if (options.max_iterations <= 0 || options.max_points < kNumParameters) {
    throw InputError(name + ": fit options max_iterations " +
                     std::to_string(options.max_iterations) + ", max_points " +
                     std::to_string(options.max_points) + " (allowed: > 0, >= 11)");
  }
  const Points points = Subsample(all_points, options.max_points);
  double extent = 0.0;
  FitState state = InitialGuess(points, extent);
  if (!(extent > 0.0)) throw InputError(name + ": all points coincide (allowed: some spread)");
  const Bounds bounds{1e-4 * extent};
  for (int k = 0; k < 3; ++k) state.a[k] = std::max(state.a[k], bounds.min_size);

  const Eigen::Index n = points.rows() + kNumEndResiduals;
  Eigen::VectorXd residuals(n), trial(n), scratch(n);
  Eigen::MatrixXd jacobian(n, kNumParameters);
  Residuals(state, points, residuals);
  SuperquadricFit fit;
  double cost = residuals.squaredNorm();
  fit.initial_cost = cost;
  double lambda = 1e-3;
  int iteration = 0;
  for (; iteration < options.max_iterations; ++iteration) {
    Jacobian(state, points, extent, bounds, jacobian, scratch);
    NormalMatrix normal = jacobian.transpose() * jacobian;
    ParameterVector gradient = jacobian.transpose() * residuals;
    FreezeActiveBounds(state, bounds, normal, gradient);
    bool accepted = false;
    double decrease = 0.0;
    while (!accepted && lambda < 1e12) {
      NormalMatrix damped = normal;
      // Marquardt's scaling by the diagonal, floored so frozen or flat directions stay SPD.
      damped.diagonal() +=
          lambda * (normal.diagonal().array().max(1e-12 * normal.trace())).matrix();
      const ParameterVector delta = damped.ldlt().solve(-gradient);
      const FitState candidate = Apply(state, delta, bounds);
      Residuals(candidate, points, trial);
      const double trial_cost = trial.squaredNorm();
      if (std::isfinite(trial_cost) && trial_cost < cost) {
        decrease = cost - trial_cost;
        state = candidate;
        residuals.swap(trial);
        cost = trial_cost;
        lambda = std::max(lambda / 3.0, 1e-12);
        accepted = true;
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted || decrease <= options.relative_tolerance * cost) break;
  }
  fit.superquadric = ToSuperquadric(state);
  fit.final_cost = cost;
  fit.num_iterations = iteration;
  // The residual of the fit is measured on all input points, in metres.
  const Eigen::Isometry3d to_local = fit.superquadric.frame.inverse();
  double sum = 0.0;
  for (Eigen::Index i = 0; i < all_points.rows(); ++i) {
    const double d =
        RadialDistance(fit.superquadric, to_local * Eigen::Vector3d(all_points.row(i).transpose()));
    sum += d * d;
    fit.max_radial_distance = std::max(fit.max_radial_distance, std::abs(d));
  }
  fit.rms_radial_distance = std::sqrt(sum / double(all_points.rows()));
  return fit;
}

}  // namespace costume::sim
