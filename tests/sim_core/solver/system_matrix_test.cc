// The system matrix's product against a dense matrix built from the same additions by their
// definition (+B on (a, a) and (b, b), −B on (a, b) and (b, a)), independently of the class's
// storage and of its row index.

#include "sim_core/solver/system_matrix.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

namespace costume::sim {
namespace {

Eigen::Matrix3d RandomSymmetric(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r) {
    for (int c = r; c < 3; ++c) m(r, c) = m(c, r) = u(rng);
  }
  return m;
}

TEST(SystemMatrix, ProductEqualsDenseMatrixOfTheAdditions) {
  // Pairs in both orientations, a particle (5) with no coupling, one with many (0).
  const int n = 7;
  const std::vector<std::pair<int, int>> pairs{{0, 1}, {2, 0}, {0, 3}, {4, 0}, {1, 2},
                                               {6, 3}, {3, 4}, {0, 6}, {2, 6}};
  SystemMatrix a(n, pairs);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  std::mt19937 rng(7);
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d d;
    d.setRandom();  // the diagonal block need not be symmetric for the product
    a.AddToDiagonal(i, d);
    dense.block<3, 3>(3 * i, 3 * i) += d;
  }
  for (int s = 0; s < static_cast<int>(pairs.size()); ++s) {
    const Eigen::Matrix3d b = RandomSymmetric(rng);
    a.AddSpringCoupling(s, b);
    const auto [p, q] = pairs[s];
    dense.block<3, 3>(3 * p, 3 * p) += b;
    dense.block<3, 3>(3 * q, 3 * q) += b;
    dense.block<3, 3>(3 * p, 3 * q) -= b;
    dense.block<3, 3>(3 * q, 3 * p) -= b;
  }
  const Eigen::VectorXd x = Eigen::VectorXd::Random(3 * n);
  Eigen::VectorXd y = Eigen::VectorXd::Constant(3 * n, 1e300);  // must be overwritten
  a.Multiply(x, y);
  EXPECT_LT((y - dense * x).norm(), 1e-13 * (dense * x).norm());
  for (int i = 0; i < n; ++i) {
    EXPECT_TRUE(a.DiagonalBlock(i).isApprox(dense.block<3, 3>(3 * i, 3 * i), 1e-15));
  }
}

TEST(SystemMatrix, ClosedFormCouplingEqualsItsMatrix) {
  // identity·I + along·u uᵀ added in closed form and as a matrix give the same matrix.
  const Eigen::Vector3d u = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  SystemMatrix closed(2, {{1, 0}}), matrix(2, {{1, 0}});
  closed.AddSpringCoupling(0, 0.7, -2.5, u);
  matrix.AddSpringCoupling(0, 0.7 * Eigen::Matrix3d::Identity() - 2.5 * u * u.transpose());
  EXPECT_LT((closed.SpringBlock(0) - matrix.SpringBlock(0)).norm(), 1e-15);
  for (int i = 0; i < 2; ++i) {
    EXPECT_LT((closed.DiagonalBlock(i) - matrix.DiagonalBlock(i)).norm(), 1e-15);
  }
}

TEST(SystemMatrix, SetZeroClearsEveryValueButKeepsThePattern) {
  SystemMatrix a(3, {{0, 1}, {1, 2}});
  a.AddToDiagonal(1, Eigen::Matrix3d::Identity());
  a.AddSpringCoupling(1, Eigen::Matrix3d::Identity());
  a.SetZero();
  Eigen::VectorXd y(9);
  a.Multiply(Eigen::VectorXd::Ones(9), y);
  EXPECT_EQ(y.norm(), 0.0);
  EXPECT_EQ(a.num_springs(), 2);
  EXPECT_EQ(a.spring_ends(1), std::make_pair(1, 2));
}

}  // namespace
}  // namespace costume::sim
