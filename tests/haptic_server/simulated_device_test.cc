#include "haptic_server/simulated_device.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "sim_core/common/input_error.h"

namespace costume::haptics {
namespace {

// x(t) of m ẍ = k (X − x) − c ẋ from rest at 0, underdamped: the closed form.
double StepResponse(double t, double X, double m, double k, double c) {
  const double omega = std::sqrt(k / m);
  const double zeta = c / (2.0 * std::sqrt(k * m));
  const double omega_d = omega * std::sqrt(1.0 - zeta * zeta);
  return X * (1.0 - std::exp(-zeta * omega * t) *
                        (std::cos(omega_d * t) +
                         zeta / std::sqrt(1.0 - zeta * zeta) * std::sin(omega_d * t)));
}

TEST(SimulatedDevice, HandFollowsAStepTargetLikeTheClosedFormDampedOscillator) {
  // Two keyframes at t = 0: the hand starts at the first (origin), the target is the second.
  const Trajectory step = ParseTrajectory("0 0 0 0 1\n0 0.1 0 0 1\n", "step");
  VirtualHand hand;  // 0.2 kg, 200 N/m, 8.85 N·s/m: ζ ≈ 0.7
  SimulatedDevice device(step, hand, 1e-3);
  ASSERT_TRUE(device.Open().ok);
  DeviceState state;
  double worst = 0.0;
  for (int k = 0; k <= 1000; ++k) {
    device.Read(state);
    ASSERT_NEAR(state.time, k * 1e-3, 1e-12);
    const double expected = StepResponse(state.time, 0.1, hand.mass, hand.stiffness, hand.damping);
    worst = std::max(worst, std::abs(state.position.x() - expected));
    EXPECT_EQ(state.position.y(), 0.0);
    EXPECT_EQ(state.buttons, 1u);
    device.Write(Eigen::Vector3d::Zero());
  }
  EXPECT_LT(worst, 1e-9);  // RK4 at 1 kHz on a 5 Hz system
  // It overshoots (ζ < 1), as the closed form does: peak ≈ X (1 + exp(−πζ/√(1−ζ²))).
  EXPECT_NEAR(device.hand_position().x(), 0.1, 1e-6);
}

TEST(SimulatedDevice, ForceWrittenBackMovesTheHandToTheSpringEquilibrium) {
  SimulatedDevice device(ParseTrajectory("0 0 0 0 0\n", "still"), VirtualHand{}, 1e-3);
  ASSERT_TRUE(device.Open().ok);
  for (int k = 0; k < 5000; ++k) device.Write(Eigen::Vector3d(0, 0, 2.0));
  EXPECT_NEAR(device.hand_position().z(), 2.0 / 200.0, 1e-9);  // F / k
}

TEST(SimulatedDevice, RefusesNonFiniteForceAndClampsToItsLimit) {
  SimulatedDevice device(ParseTrajectory("0 0 0 0 0\n", "still"), VirtualHand{}, 1e-3);
  DeviceState state;
  EXPECT_EQ(device.Read(state), DeviceFault::kNotOpen);
  ASSERT_TRUE(device.Open().ok);
  EXPECT_EQ(device.Write(Eigen::Vector3d(std::nan(""), 0, 0)), DeviceFault::kNonFinite);
  EXPECT_EQ(device.applied_force(), Eigen::Vector3d::Zero());
  device.Write(Eigen::Vector3d(0, 50, 0));
  EXPECT_NEAR(device.applied_force().y(), LimitsFor(DeviceModel::kSimulated).max_force, 1e-12);
}

TEST(Trajectory, InterpolatesLinearlyStepsOnRepeatedTimesAndHoldsButtons) {
  const Trajectory t = ParseTrajectory(
      "# time x y z buttons\n"
      "0.0  0 0 0  0\n"
      "\n"
      "1.0  1 0 0  1   # grab\n"
      "1.0  1 2 0  3\n"
      "2.0  1 2 4  0\n",
      "inline");
  Eigen::Vector3d p;
  std::uint32_t b = 99;
  t.Sample(0.25, p, b);
  EXPECT_NEAR(p.x(), 0.25, 1e-15);
  EXPECT_EQ(b, 0u);
  t.Sample(1.0, p, b);
  EXPECT_EQ(p, Eigen::Vector3d(1, 2, 0));
  EXPECT_EQ(b, 3u);
  t.Sample(1.5, p, b);
  EXPECT_NEAR(p.z(), 2.0, 1e-15);
  t.Sample(9.0, p, b);
  EXPECT_EQ(p, Eigen::Vector3d(1, 2, 4));
  EXPECT_EQ(b, 0u);
  t.Sample(-1.0, p, b);
  EXPECT_EQ(p, Eigen::Vector3d(0, 0, 0));
}

// The message of the InputError thrown by parsing `text` as "traj.txt".
std::string ErrorOf(const std::string& text) {
  try {
    ParseTrajectory(text, "traj.txt");
  } catch (const sim::InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Trajectory, ErrorsNameTheFileTheLineAndTheField) {
  EXPECT_EQ(ErrorOf("0 0 0 0 0\n1 0 abc 0 0\n"),
            "traj.txt:2: field 'y' = 'abc' is not a number");
  EXPECT_EQ(ErrorOf("# header\n0 0 0 0\n"),
            "traj.txt:2: expected 5 fields (time x y z buttons), found 4");
  EXPECT_EQ(ErrorOf("0 0 0 0 0\n0.5 0 0 0 0\n0.4 0 0 0 0\n"),
            "traj.txt:3: field 'time' = 0.4 [s] is before the previous keyframe's 0.5 s: "
            "times must not decrease");
  EXPECT_EQ(ErrorOf("0 0 0 0 0\n1 0 0 -1e300 1\n"),
            "traj.txt:2: field 'z' = -1e+300 m is not allowed: a device's tip lies within ±10 m "
            "of its origin");
  EXPECT_EQ(ErrorOf("0 10 -10 0 0\n"), "(no error)");
  EXPECT_EQ(ErrorOf("0 0 0 0 4\n"),
            "traj.txt:1: field 'buttons' = 4 is not allowed: it must be an integer in 0..3 "
            "(bit 0 grab, bit 1 stretch relief)");
  EXPECT_EQ(ErrorOf("0 0 0 0 1.5\n").rfind("traj.txt:1: field 'buttons' = 1.5", 0), 0u);
  EXPECT_EQ(ErrorOf("0 0 0 inf 0\n"),
            "traj.txt:1: field 'z' = inf is not allowed: it must be a finite number");
  EXPECT_EQ(ErrorOf("-1 0 0 0 0\n"),
            "traj.txt:1: field 'time' = -1 [s] is not allowed: it must be >= 0");
  EXPECT_EQ(ErrorOf("# nothing\n\n"),
            "traj.txt: no keyframe found: a trajectory needs at least one line "
            "'time x y z buttons'");
}

TEST(Trajectory, LoadNamesTheFilePathInErrors) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / "costume_haptic_bad_trajectory.txt";
  {
    std::ofstream out(path);
    out << "0 0 0 0 0\n0.1 0 0 0 0 7\n";
  }
  try {
    LoadTrajectory(path.string());
    FAIL() << "no error";
  } catch (const sim::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path.string() + ":2: expected 5 fields", 0), 0u)
        << e.what();
  }
  std::filesystem::remove(path);
  EXPECT_THROW(LoadTrajectory("/nonexistent/costume.traj"), sim::InputError);
}

}  // namespace
}  // namespace costume::haptics
