// Strain limiting: springs come back to the length the step meant (its first-order length),
// structural springs to the cap whatever the step meant, momentum is kept and kinetic energy
// lost, pins hold, planes keep particles outside, and what the step meant is left alone.
#include "sim_core/solver/strain_limit.h"

#include <gtest/gtest.h>

#include <cmath>

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

/// One limit as after a step: the step started at `start` and the solve left `state`.
StrainLimitReport LimitAfterStep(const ClothModel& model, const Points& start, ClothState& state,
                                 double limit = 0.1, std::span<const ShellPlane> planes = {}) {
  StrainLimiter limiter(model);
  limiter.BeginStep(start);
  StrainLimitSettings settings;
  settings.limit = limit;
  settings.tolerance = 1e-9;
  limiter.SetTargets(model, settings, state.positions);
  limiter.AddPlanes(planes);
  return limiter.Limit(model, settings, state);
}

double Length(const ClothState& state) {
  return (state.positions.row(1) - state.positions.row(0)).norm();
}

TEST(StrainLimiter, ATurnedSpringComesBackToTheLengthTheStepMeant) {
  // The free end of a pinned unit spring moves straight across it by tan(θ) (as a linearised
  // step moves it when the spring turns through θ): the step meant the length u₀·d₁ = 1, and
  // the spring came out 1/cos θ long.
  const auto model = Pair(1.0, 1.0, SpringKind::kStructural, {0});
  const Points start = ClothState::AtRest(*model).positions;
  ClothState state = ClothState::AtRest(*model);
  const double theta = 0.3;
  state.positions.row(1) << 1.0, std::tan(theta), 0.0;
  ASSERT_NEAR(Length(state), 1.0 / std::cos(theta), 1e-12);  // 4.7 % long
  LimitAfterStep(*model, start, state);
  EXPECT_NEAR(Length(state), 1.0 + kFreeStretch, 1e-9);
  // Along the spring, towards the pin: the direction it points in is kept.
  EXPECT_NEAR(std::atan2(state.positions(1, 1), state.positions(1, 0)), theta, 1e-12);
}

TEST(StrainLimiter, LeavesTheStretchTheStepMeant) {
  // The step moved the end 3 % along the spring: elastic stretch, not a turn.
  const auto model = Pair(1.0, 1.0, SpringKind::kStructural, {0});
  const Points start = ClothState::AtRest(*model).positions;
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 1.03;
  EXPECT_EQ(LimitAfterStep(*model, start, state).corrections, 0);
  EXPECT_EQ(state.positions(1, 0), 1.03);
}

TEST(StrainLimiter, CapsAStructuralSpringWhateverTheStepMeantSplittingByInverseMass) {
  const auto model = Pair(1.0, 3.0, SpringKind::kStructural);
  const Points start = ClothState::AtRest(*model).positions;
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 1.5;  // 50 % strain, all of it along the spring
  state.velocities << -0.2, 0, 0, 0.1, 0.3, 0;  // separating at 0.3 m/s along x
  const Eigen::Vector3d momentum =
      1.0 * state.velocities.row(0).transpose() + 3.0 * state.velocities.row(1).transpose();
  const double kinetic_before = 0.5 * (1.0 * state.velocities.row(0).squaredNorm() +
                                       3.0 * state.velocities.row(1).squaredNorm());
  EXPECT_GE(LimitAfterStep(*model, start, state).corrections, 1);
  EXPECT_NEAR(Length(state), 1.1, 1e-9);
  // The light end moves three times as far as the heavy one: 0.3 m and 0.1 m.
  EXPECT_NEAR(state.positions(0, 0), 0.3, 1e-9);
  EXPECT_NEAR(state.positions(1, 0), 1.4, 1e-9);
  // The ends stop separating along the spring; across it nothing changes.
  EXPECT_NEAR(state.velocities(1, 0) - state.velocities(0, 0), 0.0, 1e-12);
  EXPECT_NEAR(state.velocities(1, 1), 0.3, 1e-12);
  const Eigen::Vector3d after =
      1.0 * state.velocities.row(0).transpose() + 3.0 * state.velocities.row(1).transpose();
  EXPECT_LT((after - momentum).norm(), 1e-12);
  const double kinetic_after = 0.5 * (1.0 * state.velocities.row(0).squaredNorm() +
                                      3.0 * state.velocities.row(1).squaredNorm());
  EXPECT_LT(kinetic_after, kinetic_before);
}

TEST(StrainLimiter, ShearSpringsAreNotCappedButTurnsAreUndone) {
  // Woven fabric shears far on the bias: a shear spring the step meant to stretch 30 % keeps it.
  const auto model = Pair(1.0, 1.0, SpringKind::kShear, {0});
  const Points start = ClothState::AtRest(*model).positions;
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 1.3;
  EXPECT_EQ(LimitAfterStep(*model, start, state).corrections, 0);
  state.positions.row(1) << 1.0, 0.5, 0.0;  // turned: meant 1, came out 1.118
  LimitAfterStep(*model, start, state);
  EXPECT_NEAR(Length(state), 1.0 + kFreeStretch, 1e-9);
}

TEST(StrainLimiter, BendingSpringsAreLeftAlone) {
  const auto model = Pair(1.0, 1.0, SpringKind::kBending);
  const Points start = ClothState::AtRest(*model).positions;
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 3.0;
  EXPECT_EQ(LimitAfterStep(*model, start, state).corrections, 0);
  EXPECT_EQ(state.positions(1, 0), 3.0);
}

TEST(StrainLimiter, APinnedOrFixedEndDoesNotMove) {
  const auto model = Pair(1.0, 1.0, SpringKind::kStructural, {0});
  const Points start = ClothState::AtRest(*model).positions;
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 2.0;
  LimitAfterStep(*model, start, state);
  EXPECT_EQ(state.positions(0, 0), 0.0);
  EXPECT_NEAR(state.positions(1, 0), 1.1, 1e-9);

  const auto free_pair = Pair(1.0, 1.0, SpringKind::kStructural);
  StrainLimiter limiter(*free_pair);
  limiter.BeginStep(start);
  state = ClothState::AtRest(*free_pair);
  state.positions(1, 0) = 2.0;
  StrainLimitSettings settings;
  limiter.SetTargets(*free_pair, settings, state.positions);
  limiter.Limit(*free_pair, settings, state, /*fixed=*/{0, 1});
  EXPECT_EQ(state.positions(1, 0), 2.0);  // both held: nothing can move
}

TEST(StrainLimiter, APlaneKeepsItsParticleOutsideAndTheSpringSlidesAlongIt) {
  // The free end lies on the floor y >= 0 and the spring, 50 % too long, runs down to the
  // pinned end at (0, -0.2) below the floor: shortened along itself, the end would go below
  // the floor; held, it ends on the floor at the capped length from the pin.
  ClothModelData data;
  data.rest_positions.resize(2, 3);
  data.rest_positions << 0, -0.2, 0, 1, 0, 0;
  data.masses = Eigen::Vector2d(1.0, 1.0);
  data.areas = Eigen::Vector2d::Zero();
  const double rest = (data.rest_positions.row(1) - data.rest_positions.row(0)).norm();
  data.springs.push_back({0, 1, SpringKind::kStructural, 100.0, 0.0, rest / 1.5});
  data.pinned = {0};
  const auto model = ClothModel::Create(data);
  ClothState state = ClothState::AtRest(*model);
  const Points start = state.positions;
  const ShellPlane floor{1, Eigen::Vector3d::UnitY(), 0.0};
  LimitAfterStep(*model, start, state, 0.1, std::span<const ShellPlane>(&floor, 1));
  EXPECT_GE(state.positions(1, 1), 0.0);
  const double capped = 1.1 * rest / 1.5;
  EXPECT_NEAR(Length(state), capped, 1e-6);
  EXPECT_NEAR(state.positions(1, 1), 0.0, 1e-6);
  EXPECT_NEAR(state.positions(1, 0), std::sqrt(capped * capped - 0.04), 1e-6);
}

}  // namespace
}  // namespace costume::sim
