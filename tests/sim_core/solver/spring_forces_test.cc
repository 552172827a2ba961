// Spring forces and Jacobians against finite differences of the force itself, and the
// documented treatment of compressed springs.
#include "sim_core/solver/spring_forces.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

namespace costume::sim {
namespace {

Spring MakeSpring(double k, double c, double rest) {
  Spring s;
  s.a = 0;
  s.b = 1;
  s.stiffness = k;
  s.damping = c;
  s.rest_length = rest;
  return s;
}

/// Central-difference ∂f_a/∂x_b (columns perturb x_b), independent of EvaluateSpring's
/// analytic blocks.
Eigen::Matrix3d FiniteDifferenceDfDxb(const Spring& s, const Eigen::Vector3d& xa,
                                      const Eigen::Vector3d& xb, const Eigen::Vector3d& va,
                                      const Eigen::Vector3d& vb) {
  const double eps = 1e-6;
  Eigen::Matrix3d jac;
  for (int c = 0; c < 3; ++c) {
    Eigen::Vector3d plus = xb, minus = xb;
    plus[c] += eps;
    minus[c] -= eps;
    const auto fp = EvaluateSpring(s, xa, plus, va, vb, JacobianMode::kExact).force_on_a;
    const auto fm = EvaluateSpring(s, xa, minus, va, vb, JacobianMode::kExact).force_on_a;
    jac.col(c) = (fp - fm) / (2 * eps);
  }
  return jac;
}

TEST(EvaluateSpring, ForceIsHookeAlongTheSpring) {
  const Spring s = MakeSpring(100.0, 0.0, 1.0);
  const auto t = EvaluateSpring(s, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1.2, 0),
                                Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                JacobianMode::kExact);
  // Stretched by 0.2 m: pulls a towards b with 100 N/m · 0.2 m = 20 N.
  EXPECT_NEAR(t.force_on_a.y(), 20.0, 1e-12);
  EXPECT_NEAR(t.force_on_a.x(), 0.0, 1e-12);
}

TEST(EvaluateSpring, ForceVanishesAtRestLength) {
  const Spring s = MakeSpring(1e4, 0.0, 0.3);
  const Eigen::Vector3d xb = Eigen::Vector3d(1, 2, 2).normalized() * 0.3;
  const auto t = EvaluateSpring(s, Eigen::Vector3d::Zero(), xb, Eigen::Vector3d::Zero(),
                                Eigen::Vector3d::Zero(), JacobianMode::kExact);
  EXPECT_LT(t.force_on_a.norm(), 1e-10);
}

TEST(EvaluateSpring, StiffnessJacobianMatchesFiniteDifferencesWhenStretched) {
  const Spring s = MakeSpring(250.0, 0.0, 0.8);
  const Eigen::Vector3d xa(0.1, -0.2, 0.3), xb(0.9, 0.4, -0.1);  // length ≈ 1.08 > 0.8
  const Eigen::Vector3d va = Eigen::Vector3d::Zero(), vb = Eigen::Vector3d::Zero();
  for (JacobianMode mode : {JacobianMode::kExact, JacobianMode::kDefinite}) {
    const auto t = EvaluateSpring(s, xa, xb, va, vb, mode);
    EXPECT_LT((t.df_dx() - FiniteDifferenceDfDxb(s, xa, xb, va, vb)).norm(),
              1e-5 * t.df_dx().norm());
  }
}

TEST(EvaluateSpring, ExactJacobianMatchesFiniteDifferencesWhenCompressed) {
  const Spring s = MakeSpring(250.0, 0.0, 1.5);
  const Eigen::Vector3d xa(0.1, -0.2, 0.3), xb(0.9, 0.4, -0.1);
  const auto t = EvaluateSpring(s, xa, xb, {0, 0, 0}, {0, 0, 0}, JacobianMode::kExact);
  EXPECT_LT((t.df_dx() - FiniteDifferenceDfDxb(s, xa, xb, {0, 0, 0}, {0, 0, 0})).norm(),
            1e-5 * t.df_dx().norm());
}

TEST(EvaluateSpring, DefiniteModeDropsOnlyTheNegativeTransverseTermOfCompressedSprings) {
  const Spring s = MakeSpring(250.0, 0.0, 1.5);
  const Eigen::Vector3d xa(0.1, -0.2, 0.3), xb(0.9, 0.4, -0.1);
  const auto exact = EvaluateSpring(s, xa, xb, {0, 0, 0}, {0, 0, 0}, JacobianMode::kExact);
  const auto definite = EvaluateSpring(s, xa, xb, {0, 0, 0}, {0, 0, 0}, JacobianMode::kDefinite);
  // Independent form of the dropped term: k (1 − L/ℓ)(I − ûûᵀ).
  const Eigen::Vector3d d = xb - xa;
  const Eigen::Vector3d u = d.normalized();
  const Eigen::Matrix3d dropped =
      250.0 * (1 - 1.5 / d.norm()) * (Eigen::Matrix3d::Identity() - u * u.transpose());
  EXPECT_LT((exact.df_dx() - definite.df_dx() - dropped).norm(), 1e-9);
  // What remains is positive semi-definite: k ûûᵀ.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(definite.df_dx());
  EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-9);
  EXPECT_NEAR(eig.eigenvalues().maxCoeff(), 250.0, 1e-9);
}

TEST(EvaluateSpring, ProductWithoutTheMatrixEqualsTheMatrixProduct) {
  const Spring s = MakeSpring(250.0, 2.0, 0.8);
  const Eigen::Vector3d xa(0.1, -0.2, 0.3), xb(0.9, 0.4, -0.1), w(0.3, -1.1, 0.7);
  for (JacobianMode mode : {JacobianMode::kExact, JacobianMode::kDefinite}) {
    const auto t = EvaluateSpring(s, xa, xb, {0, 0, 0}, {0, 0, 0}, mode);
    EXPECT_LT((t.DfDxTimes(w) - t.df_dx() * w).norm(), 1e-12 * (t.df_dx() * w).norm());
  }
  // Zero length: k I.
  const auto zero = EvaluateSpring(s, xa, xa, {0, 0, 0}, {0, 0, 0}, JacobianMode::kExact);
  EXPECT_LT((zero.df_dx() - 250.0 * Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((zero.DfDxTimes(w) - 250.0 * w).norm(), 1e-12);
}

TEST(EvaluateSpring, DampingJacobianMatchesFiniteDifferences) {
  const Spring s = MakeSpring(10.0, 3.0, 1.0);
  const Eigen::Vector3d xa(0, 0, 0), xb(0.3, 0.9, 0.2), va(0.1, 0.2, -0.3);
  const Eigen::Vector3d vb(-0.5, 0.1, 0.4);
  const double eps = 1e-6;
  Eigen::Matrix3d fd;
  for (int c = 0; c < 3; ++c) {
    Eigen::Vector3d plus = vb, minus = vb;
    plus[c] += eps;
    minus[c] -= eps;
    fd.col(c) = (EvaluateSpring(s, xa, xb, va, plus, JacobianMode::kExact).force_on_a -
                 EvaluateSpring(s, xa, xb, va, minus, JacobianMode::kExact).force_on_a) /
                (2 * eps);
  }
  const auto t = EvaluateSpring(s, xa, xb, va, vb, JacobianMode::kExact);
  EXPECT_LT((t.df_dv() - fd).norm(), 1e-7);
}

TEST(ComputeForceJacobians, AssembledMatrixMatchesFiniteDifferencesOfTotalForce) {
  // A small random cloth-like cluster: four particles, all six springs, stretched.
  ClothModelData data;
  data.rest_positions.resize(4, 3);
  data.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  data.masses = Eigen::VectorXd::Constant(4, 0.1);
  data.areas = Eigen::VectorXd::Constant(4, 0.25);
  data.drag = Eigen::VectorXd::Constant(4, 0.05);
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      Spring s = MakeSpring(50.0 + a + b, 0.2, 0.5);
      s.a = a;
      s.b = b;
      data.springs.push_back(s);
    }
  }
  const auto model = ClothModel::Create(data);
  ClothState state = ClothState::AtRest(*model);
  state.velocities.setConstant(0.1);
  ExternalForces external;
  Eigen::SparseMatrix<double> dfdx, dfdv;
  ComputeForceJacobians(*model, state, external, JacobianMode::kExact, &dfdx, &dfdv);
  const double eps = 1e-6;
  Eigen::MatrixXd fd(12, 12);
  for (int j = 0; j < 12; ++j) {
    ClothState plus = state, minus = state;
    plus.positions.data()[j] += eps;
    minus.positions.data()[j] -= eps;
    fd.col(j) = (ComputeForces(*model, plus, external) - ComputeForces(*model, minus, external)) /
                (2 * eps);
  }
  // The damping force's position derivative is left out by design (B&W); with the small
  // velocities here it is below the tolerance chosen.
  EXPECT_LT((Eigen::MatrixXd(dfdx) - fd).norm(), 2e-3 * fd.norm());
}

TEST(StructuralStrain, MeasuresStretchOfStructuralSpringsOnly) {
  ClothModelData data;
  data.rest_positions.resize(3, 3);
  data.rest_positions << 0, 0, 0, 1, 0, 0, 2, 0, 0;
  data.masses = Eigen::VectorXd::Ones(3);
  data.areas = Eigen::VectorXd::Ones(3);
  Spring s1 = MakeSpring(1, 0, 1), s2 = MakeSpring(1, 0, 1), bend = MakeSpring(1, 0, 2);
  s2.a = 1;
  s2.b = 2;
  bend.b = 2;
  bend.kind = SpringKind::kBending;
  data.springs = {s1, s2, bend};
  const auto model = ClothModel::Create(data);
  Points x = model->rest_positions();
  x(2, 0) = 2.5;  // second spring 50 % longer, first unchanged
  const StrainStats stats = StructuralStrain(*model, x);
  EXPECT_NEAR(stats.max, 0.5, 1e-12);
  EXPECT_NEAR(stats.mean, 0.25, 1e-12);
  EXPECT_EQ(stats.max_spring, 1);  // s2, the stretched one
}

}  // namespace
}  // namespace costume::sim
