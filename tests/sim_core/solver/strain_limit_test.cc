// Strain limiting: over-stretched springs come back to the limit, momentum is kept, pins
// hold, and cloth within the limit is untouched.
#include "sim_core/solver/strain_limit.h"

#include <gtest/gtest.h>

namespace costume::sim {
namespace {

std::shared_ptr<const ClothModel> Pair(double ma, double mb, SpringKind kind,
                                       std::vector<int> pinned = {}) {
  ClothModelData data;
  data.rest_positions.resize(2, 3);
  data.rest_positions << 0, 0, 0, 1, 0, 0;
  data.masses = Eigen::Vector2d(ma, mb);
  data.areas = Eigen::Vector2d::Zero();
  data.springs.push_back({0, 1, kind, 100.0, 0.0, 1.0});
  data.pinned = std::move(pinned);
  return ClothModel::Create(data);
}

TEST(LimitStrain, ShortensToTheLimitSplittingByInverseMassKeepingMomentumLosingEnergy) {
  const auto model = Pair(1.0, 3.0, SpringKind::kStructural);
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 1.5;  // 50 % strain
  state.velocities << -0.2, 0, 0, 0.1, 0.3, 0;  // separating at 0.3 m/s along x
  const Eigen::Vector3d momentum =
      1.0 * state.velocities.row(0).transpose() + 3.0 * state.velocities.row(1).transpose();
  EXPECT_EQ(LimitStrain(*model, 0.1, 4, state), 1);
  EXPECT_NEAR((state.positions.row(1) - state.positions.row(0)).norm(), 1.1, 1e-12);
  // The light end moves three times as far as the heavy one: 0.3 m and 0.1 m.
  EXPECT_NEAR(state.positions(0, 0), 0.3, 1e-12);
  EXPECT_NEAR(state.positions(1, 0), 1.4, 1e-12);
  // The ends stop separating along the spring; across it nothing changes.
  EXPECT_NEAR(state.velocities(1, 0) - state.velocities(0, 0), 0.0, 1e-12);
  EXPECT_NEAR(state.velocities(1, 1), 0.3, 1e-12);
  const Eigen::Vector3d after =
      1.0 * state.velocities.row(0).transpose() + 3.0 * state.velocities.row(1).transpose();
  EXPECT_LT((after - momentum).norm(), 1e-9);
  const auto kinetic = [&](const ClothState& st) {
    return 0.5 * (1.0 * st.velocities.row(0).squaredNorm() + 3.0 * st.velocities.row(1).squaredNorm());
  };
  ClothState before = ClothState::AtRest(*model);
  before.velocities << -0.2, 0, 0, 0.1, 0.3, 0;
  EXPECT_LT(kinetic(state), kinetic(before));
}

TEST(LimitStrain, PinnedEndDoesNotMove) {
  const auto model = Pair(1.0, 1.0, SpringKind::kShear, {0});
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 2.0;
  LimitStrain(*model, 0.1, 4, state);
  EXPECT_EQ(state.positions(0, 0), 0.0);
  EXPECT_NEAR(state.positions(1, 0), 1.1, 1e-12);
}

TEST(LimitStrain, LeavesSpringsWithinTheLimitAndBendingSpringsAlone) {
  auto model = Pair(1.0, 1.0, SpringKind::kStructural);
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 1.09;
  EXPECT_EQ(LimitStrain(*model, 0.1, 4, state), 0);
  EXPECT_EQ(state.positions(1, 0), 1.09);
  model = Pair(1.0, 1.0, SpringKind::kBending);
  state.positions(1, 0) = 3.0;
  EXPECT_EQ(LimitStrain(*model, 0.1, 4, state), 0);
}

}  // namespace
}  // namespace costume::sim
