// Superquadrics: the inside-outside function against closed forms, its gradient and the
// fit's Jacobian against finite differences, and the Solina–Bajcsy fit recovering a known
// superquadric from noisy samples in an arbitrary pose and fitting an open tube along its
// length.
#include "sim_core/collision/superquadric.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kPi = std::numbers::pi;

Superquadric Make(double a1, double a2, double a3, double e1, double e2) {
  Superquadric s;
  s.a1 = a1;
  s.a2 = a2;
  s.a3 = a3;
  s.e1 = e1;
  s.e2 = e2;
  return s;
}

TEST(InsideOutside, IsTheEllipsoidQuadricForUnitExponents) {
  const Superquadric s = Make(0.3, 0.2, 0.5, 1.0, 1.0);
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.1, -0.05, 0.2), Eigen::Vector3d(-0.4, 0.3, 0.0),
        Eigen::Vector3d(0.0, 0.0, -0.7)}) {
    const double expected = p.x() * p.x() / 0.09 + p.y() * p.y() / 0.04 + p.z() * p.z() / 0.25;
    EXPECT_NEAR(InsideOutside(s, p), expected, 1e-12 * expected);
  }
}

TEST(InsideOutside, SmallExponentsGiveABoxWithCornersInside) {
  const Superquadric s = Make(0.3, 0.2, 0.5, 0.1, 0.1);
  // Each coordinate at 90 % of the half size: F = 3·0.9^20 (a box contains its corners).
  const Eigen::Vector3d corner(0.27, 0.18, 0.45);
  EXPECT_NEAR(InsideOutside(s, corner), 3.0 * std::pow(0.9, 20.0), 1e-12);
  EXPECT_LT(InsideOutside(s, corner), 1.0);
  // 5 % beyond a face: F = 1.05^20 > 1.
  EXPECT_NEAR(InsideOutside(s, {0.315, 0.0, 0.0}), std::pow(1.05, 20.0), 1e-9);
  EXPECT_GT(InsideOutside(s, {0.0, 0.0, 0.51}), 1.0);
}

TEST(InsideOutside, IsOneOnParametricPointsAndScalesWithTheRayParameter) {
  for (const Superquadric& s : {Make(0.3, 0.2, 0.5, 0.4, 1.6), Make(0.1, 0.25, 0.15, 1.8, 0.3),
                                Make(0.2, 0.2, 0.2, 0.1, 2.0)}) {
    for (double eta = -1.5; eta <= 1.5; eta += 0.25) {
      for (double omega = -3.1; omega <= 3.1; omega += 0.37) {
        const Eigen::Vector3d p = ParametricSurfacePoint(s, eta, omega);
        EXPECT_NEAR(InsideOutside(s, p), 1.0, 1e-9) << eta << " " << omega;
        for (double scale : {0.3, 2.5}) {
          EXPECT_NEAR(InsideOutside(s, scale * p), std::pow(scale, 2.0 / s.e1),
                      1e-9 * std::pow(scale, 2.0 / s.e1));
        }
      }
    }
  }
}

TEST(ParametricAngles, InvertTheParametricFormAlongRays) {
  const Superquadric s = Make(0.3, 0.2, 0.5, 0.6, 1.4);
  for (double eta = -1.4; eta <= 1.4; eta += 0.2) {
    for (double omega = -3.0; omega <= 3.0; omega += 0.5) {
      const Eigen::Vector2d angles =
          ParametricAngles(s, 1.7 * ParametricSurfacePoint(s, eta, omega));
      EXPECT_NEAR(angles[0], eta, 1e-9);
      EXPECT_NEAR(angles[1], omega, 1e-9);
    }
  }
}

TEST(InsideOutsideGradient, MatchesCentralDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-0.6, 0.6);
  for (const Superquadric& s : {Make(0.3, 0.2, 0.5, 1.0, 1.0), Make(0.3, 0.2, 0.5, 0.3, 1.7),
                                Make(0.1, 0.25, 0.15, 1.9, 0.5)}) {
    for (int trial = 0; trial < 50; ++trial) {
      const Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
      const Eigen::Vector3d gradient = InsideOutsideGradient(s, p);
      for (int k = 0; k < 3; ++k) {
        const double step = 1e-6;
        Eigen::Vector3d plus = p, minus = p;
        plus[k] += step;
        minus[k] -= step;
        const double numeric = (InsideOutside(s, plus) - InsideOutside(s, minus)) / (2 * step);
        EXPECT_NEAR(gradient[k], numeric, 1e-5 * (1.0 + std::abs(numeric))) << s.e1 << " " << k;
      }
    }
  }
}

// The fit's residual of a point q fixed in the parent frame, written out here from its
// definition: sqrt(a1 a2 a3)·(F(Rᵀ(q − t))^e1 − 1).
double FitResidualOf(const Superquadric& s, const Eigen::Vector3d& q) {
  return std::sqrt(s.a1 * s.a2 * s.a3) *
         (std::pow(InsideOutside(s, s.frame.inverse() * q), s.e1) - 1.0);
}

// The superquadric with its k-th fit parameter moved by h: a1, a2, a3, e1, e2, the frame's
// translation, and a rotation increment applied as R·exp([h·e]×).
Superquadric Moved(Superquadric s, int k, double h) {
  double* field[5] = {&s.a1, &s.a2, &s.a3, &s.e1, &s.e2};
  if (k < 5) {
    *field[k] += h;
  } else if (k < 8) {
    s.frame.translation()[k - 5] += h;
  } else {
    s.frame.linear() =
        s.frame.linear() * Eigen::AngleAxisd(h, Eigen::Vector3d::Unit(k - 8)).toRotationMatrix();
  }
  return s;
}

// The fit's closed-form Jacobian against central differences of the residual's definition,
// for every parameter, on round, box-like and diamond-like shapes in an arbitrary pose, at
// points inside, outside and near the surface. A wrong term (say, the rotation's sign or
// the sizes' sqrt(a1 a2 a3) factor left out) is off by far more than the tolerance.
TEST(SuperquadricFitResidual, DerivativesMatchCentralDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coordinate(-0.35, 0.35);
  const Eigen::Isometry3d pose = Eigen::Translation3d(0.3, 1.1, -0.2) *
                                 Eigen::AngleAxisd(0.8, Eigen::Vector3d(1, 2, -0.5).normalized());
  for (Superquadric s : {Make(0.3, 0.2, 0.5, 1.0, 1.0), Make(0.3, 0.2, 0.5, 0.3, 1.7),
                         Make(0.1, 0.25, 0.15, 1.9, 0.5)}) {
    s.frame = pose;
    for (int trial = 0; trial < 40; ++trial) {
      const Eigen::Vector3d local(coordinate(rng), coordinate(rng), coordinate(rng));
      const Eigen::Vector3d q = pose * local;
      SuperquadricFitGradient gradient;
      EXPECT_NEAR(SuperquadricFitResidual(s, local, &gradient), FitResidualOf(s, q), 1e-12);
      for (int k = 0; k < 11; ++k) {
        const double step = 1e-6;
        const double numeric =
            (FitResidualOf(Moved(s, k, step), q) - FitResidualOf(Moved(s, k, -step), q)) /
            (2 * step);
        EXPECT_NEAR(gradient[k], numeric, 1e-5 * (1.0 + std::abs(numeric)))
            << "e1 " << s.e1 << " parameter " << k << " at " << local.transpose();
      }
    }
  }
}

TEST(RadialSurfacePoint, LiesOnTheSurfaceAndOnTheRay) {
  const Superquadric s = Make(0.3, 0.2, 0.5, 0.5, 1.5);
  const Eigen::Vector3d p(0.7, -0.2, 0.4);
  const Eigen::Vector3d surface = RadialSurfacePoint(s, p);
  EXPECT_NEAR(InsideOutside(s, surface), 1.0, 1e-12);
  EXPECT_NEAR(surface.normalized().dot(p.normalized()), 1.0, 1e-12);
  EXPECT_NEAR(RadialDistance(s, p), p.norm() - surface.norm(), 1e-12);
  EXPECT_GT(RadialDistance(s, p), 0.0);
  EXPECT_LT(RadialDistance(s, 0.5 * surface), 0.0);
  // On a sphere the radial distance is the Euclidean one.
  EXPECT_NEAR(RadialDistance(Make(0.2, 0.2, 0.2, 1.0, 1.0), {0.1, 0.2, -0.2}), 0.1, 1e-12);
}

/// Points of `truth` at random parametric angles, moved by `truth.frame`, with Gaussian noise.
Points Sample(const Superquadric& truth, int count, double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> eta(-kPi / 2, kPi / 2), omega(-kPi, kPi);
  std::normal_distribution<double> jitter(0.0, noise);
  Points points(count, 3);
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d p = truth.frame * ParametricSurfacePoint(truth, eta(rng), omega(rng));
    points.row(i) = (p + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng))).transpose();
  }
  return points;
}

void ExpectRecovered(const Superquadric& truth, const SuperquadricFit& fit) {
  const Superquadric& s = fit.superquadric;
  EXPECT_NEAR(s.a1, truth.a1, 0.02 * truth.a1);
  EXPECT_NEAR(s.a2, truth.a2, 0.02 * truth.a2);
  EXPECT_NEAR(s.a3, truth.a3, 0.02 * truth.a3);
  EXPECT_NEAR(s.e1, truth.e1, 0.05);
  EXPECT_NEAR(s.e2, truth.e2, 0.05);
  EXPECT_LT((s.frame.translation() - truth.frame.translation()).norm(), 0.02 * truth.a2);
  // Axes agree up to sign (the superquadric is symmetric under each axis' reflection).
  const Eigen::Matrix3d agreement =
      (s.frame.linear().transpose() * truth.frame.linear()).cwiseAbs();
  EXPECT_TRUE(agreement.isApprox(Eigen::Matrix3d::Identity(), 0.02)) << agreement;
}

TEST(FitSuperquadric, RecoversAKnownSuperquadricFromNoisyPointsInAnArbitraryPose) {
  for (const Superquadric& shape :
       {Make(0.12, 0.07, 0.2, 0.5, 1.5), Make(0.12, 0.07, 0.2, 1.0, 0.3),
        Make(0.12, 0.07, 0.2, 1.6, 1.0)}) {
    Superquadric truth = shape;
    truth.frame = Eigen::Translation3d(0.3, 1.1, -0.2) *
                  Eigen::AngleAxisd(0.8, Eigen::Vector3d(1, 2, -0.5).normalized());
    const SuperquadricFit fit = FitSuperquadric(Sample(truth, 1500, 0.0005, 3), "test points");
    ExpectRecovered(truth, fit);
    EXPECT_LT(fit.rms_radial_distance, 0.002);
    EXPECT_LT(fit.final_cost, fit.initial_cost);
  }
}

TEST(FitSuperquadric, ExponentsStayWithinTheirBounds) {
  // A box sharper than e = 0.1 can express: the fit must stop at the bound.
  Points points(6 * 100, 3);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d half(0.1, 0.07, 0.2);
  for (int face = 0; face < 6; ++face) {
    for (int i = 0; i < 100; ++i) {
      Eigen::Vector3d p(u(rng), u(rng), u(rng));
      p[face / 2] = face % 2 ? 1.0 : -1.0;
      points.row(face * 100 + i) = p.cwiseProduct(half).transpose();
    }
  }
  const SuperquadricFit fit = FitSuperquadric(points, "box");
  EXPECT_GE(fit.superquadric.e1, kMinSuperquadricExponent);
  EXPECT_GE(fit.superquadric.e2, kMinSuperquadricExponent);
  EXPECT_LT(fit.superquadric.e1, 0.2);
  EXPECT_LT(fit.superquadric.e2, 0.2);
}

// A thigh's skin: a tube open at both ends, 45 cm long, its radius tapering from 8 cm at the
// hip to 4.5 cm at the knee. The fitted superquadric is the tube's shape, its ends within
// 10 % of the tube's half length of the tube's (plus the fit's slack) and its centre, where
// the collider's rays start, within a sixth of the length of the tube's middle. Without the
// fit's end residuals it came out as the wide half of an ellipsoid twice the tube's length,
// centred near the hip end (as MakeHuman's thighs did).
TEST(FitSuperquadric, AnOpenTaperingTubeIsFittedAlongItsLengthNotAsHalfALongerShape) {
  constexpr double kLength = 0.45, kHip = 0.08, kKnee = 0.045;
  constexpr int kRings = 40, kAround = 36;
  Points points(kRings * kAround, 3);
  for (int i = 0; i < kRings; ++i) {
    const double z = kLength * i / (kRings - 1);
    const double r = kHip + (kKnee - kHip) * z / kLength;
    for (int j = 0; j < kAround; ++j) {
      const double phi = 2 * kPi * j / kAround;
      points.row(i * kAround + j) << r * std::cos(phi), r * std::sin(phi), z;
    }
  }
  const SuperquadricFit fit = FitSuperquadric(points, "open tube");
  const Superquadric& s = fit.superquadric;
  const Eigen::Vector3d axis = s.frame.linear().col(2);
  const Eigen::Vector3d centre = s.frame.translation();
  EXPECT_GT(std::abs(axis.z()), 0.99);  // the long axis is the tube's
  EXPECT_NEAR(centre.z(), 0.5 * kLength, kLength / 6);
  EXPECT_LT(s.a3, 0.5 * kLength * 1.2);
  EXPECT_LT(std::hypot(centre.x(), centre.y()), 0.01);
  std::printf("a = %.1f %.1f %.1f mm, centre at %.1f mm along the tube, RMS %.1f mm\n", 1e3 * s.a1,
              1e3 * s.a2, 1e3 * s.a3, 1e3 * centre.z(), 1e3 * fit.rms_radial_distance);
}

TEST(FitSuperquadric, RefusesTooFewPoints) {
  EXPECT_THROW(FitSuperquadric(Points::Random(5, 3), "five points"), InputError);
  EXPECT_THROW(FitSuperquadric(Points::Zero(30, 3), "one point repeated"), InputError);
}

}  // namespace
}  // namespace costume::sim
