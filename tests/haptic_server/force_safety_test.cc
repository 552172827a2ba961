#include "haptic_server/force_safety.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "sim_core/common/input_error.h"

namespace costume::haptics {
namespace {

constexpr double kDt = 1e-3;

ForceSafetyOptions Options(DeviceLimits limits) {
  ForceSafetyOptions options;
  options.limits = limits;
  return options;
}

// A grab with a fresh patch at every tick and a constant force at zero displacement.
SafetyInput Holding(double now, const Eigen::Vector3d& force) {
  SafetyInput in;
  in.now = now;
  in.last_patch_time = now;
  in.grab_active = true;
  in.base_force = in.force = force;
  return in;
}

// Runs `ticks` ticks of Holding and returns the last output; time advances kDt per tick.
Eigen::Vector3d RampUp(ForceSafety& safety, const Eigen::Vector3d& force, int ticks) {
  Eigen::Vector3d out;
  for (int k = 1; k <= ticks; ++k) out = safety.Step(Holding(k * kDt, force), kDt);
  return out;
}

TEST(DeviceLimits, TableHoldsTheVendorFigures) {
  EXPECT_EQ(LimitsFor(DeviceModel::kTouch).max_force, 3.3);
  EXPECT_EQ(LimitsFor(DeviceModel::kTouch).max_stiffness, 400.0);
  EXPECT_EQ(LimitsFor(DeviceModel::kOmni).max_force, 3.3);
  EXPECT_EQ(LimitsFor(DeviceModel::kOmni).max_stiffness, 700.0);
  EXPECT_EQ(LimitsFor(DeviceModel::kDesktop).max_force, 7.9);
  EXPECT_EQ(LimitsFor(DeviceModel::kDesktop).max_stiffness, 1000.0);
}

struct ModelCase {
  DeviceModel model;
  double max_force;
  double max_stiffness;
};

class ForceSafetyPerModel : public ::testing::TestWithParam<ModelCase> {};

TEST_P(ForceSafetyPerModel, ClampsTheForceToTheModelsMaximumKeepingItsDirection) {
  const ModelCase c = GetParam();
  ForceSafety safety(Options(LimitsFor(c.model)));
  const Eigen::Vector3d huge = 100.0 * Eigen::Vector3d(1, 2, 2) / 3.0;  // 100 N
  const Eigen::Vector3d out = RampUp(safety, huge, 400);
  EXPECT_NEAR(out.norm(), c.max_force, 1e-12);
  EXPECT_NEAR(out.normalized().dot(huge.normalized()), 1.0, 1e-12);
  EXPECT_TRUE(safety.flags().force_clamped);
  // Below the limit nothing changes.
  const Eigen::Vector3d small(0.5 * c.max_force, 0, 0);
  ForceSafety calm(Options(LimitsFor(c.model)));
  EXPECT_NEAR((RampUp(calm, small, 400) - small).norm(), 0.0, 1e-12);
  EXPECT_FALSE(calm.flags().force_clamped);
}

TEST_P(ForceSafetyPerModel, LimitsTheRenderedStiffnessToTheModelsMaximum) {
  const ModelCase c = GetParam();
  ForceSafety safety(Options(LimitsFor(c.model)));
  RampUp(safety, Eigen::Vector3d::Zero(), 400);
  // A 10,000 N/m patch and the tip 0.1 mm away from the capture point: 1 N wanted, but at most
  // max_stiffness · 1e-4 m may follow the tip.
  SafetyInput in = Holding(0.401, Eigen::Vector3d::Zero());
  in.tip_displacement = Eigen::Vector3d(0, 1e-4, 0);
  in.force = 1e4 * in.tip_displacement;
  const Eigen::Vector3d out = safety.Step(in, kDt);
  EXPECT_NEAR(out.y(), c.max_stiffness * 1e-4, 1e-12);
  EXPECT_TRUE(safety.flags().stiffness_limited);
  // A soft patch (100 N/m) passes unchanged.
  in.force = 100.0 * in.tip_displacement;
  EXPECT_NEAR(safety.Step(in, kDt).y(), 100.0 * 1e-4, 1e-15);
  EXPECT_FALSE(safety.flags().stiffness_limited);
}

INSTANTIATE_TEST_SUITE_P(Models, ForceSafetyPerModel,
                         ::testing::Values(ModelCase{DeviceModel::kTouch, 3.3, 400.0},
                                           ModelCase{DeviceModel::kOmni, 3.3, 700.0},
                                           ModelCase{DeviceModel::kDesktop, 7.9, 1000.0}));

TEST(ForceSafety, RampsInAlongARaisedCosineOver200Ms) {
  ForceSafety safety(Options({10.0, 1000.0}));
  const Eigen::Vector3d f(0, 0, 2.0);
  for (int k = 1; k <= 250; ++k) {
    const Eigen::Vector3d out = safety.Step(Holding(k * kDt, f), kDt);
    const double phase = std::min(1.0, k / 200.0);
    const double expected = 0.5 * (1.0 - std::cos(std::numbers::pi * phase));
    ASSERT_NEAR(out.z(), 2.0 * expected, 1e-9) << "tick " << k;
  }
  // Spot values by hand: a quarter of the way, (1 − cos π/4)/2 = 0.14644660940672624.
  ForceSafety again(Options({10.0, 1000.0}));
  EXPECT_NEAR(RampUp(again, Eigen::Vector3d(1, 0, 0), 50).x(), 0.14644660940672624, 1e-9);
  EXPECT_NEAR(RampUp(again, Eigen::Vector3d(1, 0, 0), 50).x(), 0.5, 1e-9);  // ticks 51..100
}

TEST(ForceSafety, FadesToZeroWithin50MsAfterPatchesStop) {
  ForceSafety safety(Options({10.0, 1000.0}));
  const Eigen::Vector3d f(1.0, 0, 0);
  RampUp(safety, f, 300);  // full gain; last patch at t = 0.300 s
  const double last_patch = 0.300;
  double previous = 1.0;
  for (int k = 1; k <= 80; ++k) {
    SafetyInput in = Holding(last_patch + k * kDt, f);
    in.last_patch_time = last_patch;
    const double out = safety.Step(in, kDt).x();
    // Stale once more than 25 ms have passed (k = 25 sits on the boundary, up to rounding of
    // the times); the fade then takes 25 ms.
    if (k < 25) {
      ASSERT_NEAR(out, 1.0, 1e-12) << k << " ms after the last patch: not yet stale";
    } else if (k >= 26 && k <= 48) {
      ASSERT_LT(out, previous) << k << " ms";
      ASSERT_GT(out, 0.0) << k << " ms";
      ASSERT_TRUE(safety.flags().stale);
    } else if (k >= 50) {
      ASSERT_EQ(out, 0.0) << k << " ms after the last patch";
    }
    ASSERT_LE(out, previous);
    previous = out;
  }
  EXPECT_EQ(safety.counters().num_stale_episodes, 1u);
}

// The loop at normal priority on a loaded machine skips ticks: here every fifth runs (5 ms
// apart, each stepped with the nominal 1 ms). The force is still zero 50 ms after the last
// patch, give or take the tick that finds the deadline passed: the fade counts time, not
// ticks (counted in ticks it lasted 125 ms, and grab_release_test saw 0.1 N at 57 ms).
TEST(ForceSafety, FadesToZeroWithin50MsAfterPatchesStopWhenTheLoopSkipsTicks) {
  ForceSafety safety(Options({10.0, 1000.0}));
  const Eigen::Vector3d f(1.0, 0, 0);
  RampUp(safety, f, 300);  // full gain; last patch at t = 0.300 s
  const double last_patch = 0.300;
  constexpr double kSkipped = 5e-3;
  for (int k = 1; k <= 30; ++k) {
    const double since = k * kSkipped;
    SafetyInput in = Holding(last_patch + since, f);
    in.last_patch_time = last_patch;
    const double out = safety.Step(in, kDt).x();
    if (since > 0.050 + kSkipped + 1e-9) {
      ASSERT_EQ(out, 0.0) << 1e3 * since << " ms";
    }
    if (since < 0.025 - 1e-9) {
      ASSERT_NEAR(out, 1.0, 1e-12) << 1e3 * since << " ms";
    }
  }
}

// A ramp-in, by contrast, advances by the nominal period whatever time passed: after a stall
// of the loop the force must not jump up.
TEST(ForceSafety, RampsInByTicksNotByTimeAfterAStall) {
  ForceSafety safety(Options({10.0, 1000.0}));
  const Eigen::Vector3d f(1.0, 0, 0);
  safety.Step(Holding(0.001, f), kDt);
  const double after_stall = safety.Step(Holding(0.101, f), kDt).x();  // 100 ms later
  EXPECT_NEAR(after_stall, 0.5 * (1.0 - std::cos(std::numbers::pi * 2.0 / 200.0)), 1e-12);
}

TEST(ForceSafety, ZeroesTheForceAtOnceOnANonFiniteValueAndRampsAgainAfter) {
  ForceSafety safety(Options({10.0, 1000.0}));
  const Eigen::Vector3d f(0, 1.0, 0);
  RampUp(safety, f, 300);
  SafetyInput bad = Holding(0.301, f);
  bad.force.y() = std::nan("");
  EXPECT_EQ(safety.Step(bad, kDt), Eigen::Vector3d::Zero());
  EXPECT_TRUE(safety.flags().non_finite);
  EXPECT_EQ(safety.counters().num_non_finite, 1u);
  bad = Holding(0.302, f);
  bad.tip_displacement.x() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(safety.Step(bad, kDt), Eigen::Vector3d::Zero());
  // Finite again: the ramp restarts from zero, first tick at phase 1/200.
  const double first = safety.Step(Holding(0.303, f), kDt).y();
  EXPECT_NEAR(first, 0.5 * (1.0 - std::cos(std::numbers::pi / 200.0)), 1e-12);
}

TEST(ForceSafety, RampsInAgainWhenPatchesResume) {
  ForceSafety safety(Options({10.0, 1000.0}));
  const Eigen::Vector3d f(1.0, 0, 0);
  RampUp(safety, f, 300);
  for (int k = 1; k <= 60; ++k) {  // stale from 26 ms, zero by 50 ms
    SafetyInput in = Holding(0.3 + k * kDt, f);
    in.last_patch_time = 0.3;
    safety.Step(in, kDt);
  }
  EXPECT_EQ(safety.gain(), 0.0);
  const double resumed = safety.Step(Holding(0.361, f), kDt).x();
  EXPECT_NEAR(resumed, 0.5 * (1.0 - std::cos(std::numbers::pi / 200.0)), 1e-12);
  EXPECT_TRUE(safety.flags().ramping);
}

TEST(ForceSafety, FadesWhenTheGrabIsReleased) {
  ForceSafety safety(Options({10.0, 1000.0}));
  RampUp(safety, Eigen::Vector3d(1, 0, 0), 300);
  SafetyInput in = Holding(0.301, Eigen::Vector3d(1, 0, 0));
  in.grab_active = false;
  for (int k = 0; k < 25; ++k) safety.Step(in, kDt);
  EXPECT_EQ(safety.gain(), 0.0);
}

TEST(ForceSafetyOptions, RefusesANonPositiveRampTime) {
  ForceSafetyOptions options;
  options.ramp_time = 0.0;
  EXPECT_THROW(ForceSafety{options}, sim::InputError);
}

}  // namespace
}  // namespace costume::haptics
