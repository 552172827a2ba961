// The devices other than the simulated one, each driven through the HapticDevice interface:
// the mouse, log playback, and the SDK-free halves of OpenHaptics and CyberGrasp.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <thread>

#include "haptic_server/cybergrasp_bridge.h"
#include "haptic_server/hd_servo_bridge.h"
#include "haptic_server/log_playback_device.h"
#include "haptic_server/mouse_device.h"
#include "sim_core/common/input_error.h"

namespace costume::haptics {
namespace {

TEST(MouseDevice, ReadsTheNewestPushedSampleWithAFiniteDifferenceVelocity) {
  MouseDevice mouse;
  HapticDevice& device = mouse;
  DeviceState state;
  EXPECT_EQ(device.Read(state), DeviceFault::kNotOpen);
  ASSERT_TRUE(device.Open().ok);
  EXPECT_EQ(device.Read(state), DeviceFault::kNoData);
  mouse.Push({1.0, Eigen::Vector3d(0.1, 0.2, 0.3), kButtonGrab});
  ASSERT_EQ(device.Read(state), DeviceFault::kNone);
  EXPECT_EQ(state.position, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(state.buttons, static_cast<std::uint32_t>(kButtonGrab));
  // Two pushes between reads: the newest wins; velocity against the last one read.
  mouse.Push({1.5, Eigen::Vector3d(9, 9, 9), 0});
  mouse.Push({2.0, Eigen::Vector3d(0.2, 0.2, 0.3), 0});
  ASSERT_EQ(device.Read(state), DeviceFault::kNone);
  EXPECT_NEAR(state.velocity.x(), 0.1, 1e-15);  // 0.1 m over 1 s
  EXPECT_EQ(state.buttons, 0u);
  // A non-finite sample is refused and the previous one kept.
  mouse.Push({2.5, Eigen::Vector3d(std::nan(""), 0, 0), 0});
  EXPECT_EQ(device.Read(state), DeviceFault::kNonFinite);
  EXPECT_EQ(state.position, Eigen::Vector3d(0.2, 0.2, 0.3));
  // Forces go back to the GUI.
  Eigen::Vector3d force;
  EXPECT_FALSE(mouse.TakeForce(force));
  device.Write(Eigen::Vector3d(1, 2, 3));
  ASSERT_TRUE(mouse.TakeForce(force));
  EXPECT_EQ(force, Eigen::Vector3d(1, 2, 3));
}

TEST(MouseDevice, HandsSamplesAcrossThreadsWithoutTearing) {
  // The GUI thread pushes samples whose three coordinates are equal; the tick must never see a
  // mix of two samples.
  MouseDevice mouse;
  ASSERT_TRUE(mouse.Open().ok);
  std::atomic<bool> done{false};
  std::thread gui([&] {
    for (int k = 1; k <= 200000; ++k) {
      const double v = k;
      mouse.Push({v, Eigen::Vector3d(v, v, v), 0});
    }
    done = true;
  });
  DeviceState state;
  double last = 0.0;
  long reads = 0;
  while (!done || reads < 10) {
    if (mouse.Read(state) == DeviceFault::kNone) {
      ASSERT_EQ(state.position.x(), state.position.y());
      ASSERT_EQ(state.position.y(), state.position.z());
      ASSERT_GE(state.position.x(), last);  // never older than what was read before
      last = state.position.x();
    }
    ++reads;
  }
  gui.join();
  mouse.Read(state);
  EXPECT_EQ(state.position.x(), 200000.0);
}

TEST(LogPlaybackDevice, ReplaysTheRecordedStatesAtTheirTimes) {
  DeviceState a, b;
  a.time = 10.0;
  a.position = Eigen::Vector3d(0.001, 0.002, 1.0 / 3.0);
  a.buttons = 1;
  b.time = 10.002;
  b.position = Eigen::Vector3d(0.1, 0.2, 0.3);
  b.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  b.velocity = Eigen::Vector3d(-1, 0, 2);
  b.buttons = 3;
  const std::string text = "# recorded\n" + FormatDeviceLogLine(a) + "\n" +
                           FormatDeviceLogLine(b) + "\n";
  LogPlaybackDevice playback(ParseDeviceLog(text, "session.log"), 1e-3);
  HapticDevice& device = playback;
  ASSERT_TRUE(device.Open().ok);
  DeviceState s;
  EXPECT_EQ(device.Read(s), DeviceFault::kNone);  // t = 10.000: a
  EXPECT_EQ(s.position, a.position);               // bit for bit through the text
  EXPECT_EQ(device.Read(s), DeviceFault::kNone);  // t = 10.001: still a
  EXPECT_EQ(s.buttons, 1u);
  EXPECT_EQ(device.Read(s), DeviceFault::kNone);  // t = 10.002: b
  EXPECT_EQ(s.position, b.position);
  EXPECT_EQ(s.velocity, b.velocity);
  EXPECT_NEAR(s.orientation.angularDistance(b.orientation), 0.0, 1e-12);
  EXPECT_EQ(s.buttons, 3u);
  EXPECT_EQ(device.Read(s), DeviceFault::kEndOfData);  // past the end: b held
  EXPECT_EQ(s.position, b.position);
  ASSERT_TRUE(device.Open().ok);  // rewinds
  device.Read(s);
  EXPECT_EQ(s.position, a.position);
}

std::string LogErrorOf(const std::string& text) {
  try {
    ParseDeviceLog(text, "s.log");
  } catch (const sim::InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(DeviceLog, ErrorsNameTheFileTheLineAndTheField) {
  EXPECT_EQ(LogErrorOf("0 0 0 0 1 0 0 0 0 0 0 0\n0 0 0 0 1 0 0 0 0 0 0 0\n"),
            "s.log:2: field 'time' = 0 [s] is not after the previous sample's 0 s: times must "
            "increase");
  EXPECT_EQ(LogErrorOf("0 10.5 0 0 1 0 0 0 0 0 0 0\n"),
            "s.log:1: field 'x' = 10.5 m is not allowed: a device's tip lies within ±10 m of its "
            "origin");
  EXPECT_EQ(LogErrorOf("0 0 0 0 2 0 0 0 0 0 0 0\n"),
            "s.log:1: field 'qw' = 2 starts a quaternion of norm 2: (qw qx qy qz) must be a unit "
            "quaternion within 1e-3");
  EXPECT_EQ(LogErrorOf("0 0 0 0 1 0 0 0 0 x 0 0\n"), "s.log:1: field 'vy' = 'x' is not a number");
  EXPECT_EQ(LogErrorOf("\n\n0 0 0\n"),
            "s.log:3: expected 12 fields (time x y z qw qx qy qz vx vy vz buttons), found 3");
}

// ---- OpenHaptics, without the SDK ------------------------------------------------------------

TEST(HdServoBridge, ConvertsMillimetresToMetresAndMapsButtonsAndOrientation) {
  HdServoBridge bridge(DeviceModel::kTouch);
  HapticDevice& device = bridge;
  ASSERT_TRUE(device.Open().ok);
  DeviceState state;
  EXPECT_EQ(device.Read(state), DeviceFault::kNoData);
  HdServoSample sample;
  sample.time = 3.0;
  sample.position_mm = {12.5, -40.0, 75.0};
  sample.velocity_mm_s = {100.0, 0.0, -250.0};
  // 90° about z, column-major: first column (0, 1, 0), second (−1, 0, 0).
  sample.transform = {0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, 12.5, -40, 75, 1};
  sample.buttons = kHdButton1 | kHdButton2 | (1 << 2);  // button 3 is ignored
  bridge.ServoExchange(sample);
  ASSERT_EQ(device.Read(state), DeviceFault::kNone);
  EXPECT_NEAR((state.position - Eigen::Vector3d(0.0125, -0.040, 0.075)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((state.velocity - Eigen::Vector3d(0.1, 0.0, -0.25)).norm(), 0.0, 1e-15);
  const Eigen::Quaterniond quarter_turn(Eigen::AngleAxisd(std::numbers::pi / 2,
                                                          Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(state.orientation.angularDistance(quarter_turn), 0.0, 1e-12);
  EXPECT_EQ(state.buttons, static_cast<std::uint32_t>(kButtonGrab | kButtonStretchRelief));
  EXPECT_EQ(ButtonsFromHd(kHdButton2), static_cast<std::uint32_t>(kButtonStretchRelief));
  EXPECT_EQ(ButtonsFromHd(0), 0u);
  sample.error = true;
  bridge.ServoExchange(sample);
  EXPECT_EQ(device.Read(state), DeviceFault::kCommunication);
}

TEST(HdServoBridge, ClampsTheForceToTheModelAndRefusesNonFinite) {
  HdServoBridge bridge(DeviceModel::kOmni);
  HapticDevice& device = bridge;
  ASSERT_TRUE(device.Open().ok);
  HdServoSample sample;
  device.Write(Eigen::Vector3d(0, 6.0, 8.0));  // 10 N
  std::array<double, 3> sent = bridge.ServoExchange(sample);
  EXPECT_NEAR(sent[1], 3.3 * 0.6, 1e-12);  // Omni: 3.3 N, direction kept
  EXPECT_NEAR(sent[2], 3.3 * 0.8, 1e-12);
  EXPECT_EQ(device.Write(Eigen::Vector3d(std::nan(""), 1, 0)), DeviceFault::kNonFinite);
  sent = bridge.ServoExchange(sample);
  EXPECT_EQ(sent, (std::array<double, 3>{0, 0, 0}));
  device.Write(Eigen::Vector3d(1, 0, 0));
  ASSERT_TRUE(device.Close().ok);
  EXPECT_EQ(bridge.ServoExchange(sample), (std::array<double, 3>{0, 0, 0}));  // closed
}

TEST(HdServoBridge, ServoZeroesTheForceWhenTheTickStopsWriting) {
  HdServoBridge bridge;
  ASSERT_TRUE(bridge.Open().ok);
  HdServoSample sample;
  bridge.Write(Eigen::Vector3d(1.0, 0, 0));
  for (int frame = 0; frame < HdServoBridge::kWatchdogFrames; ++frame) {
    ASSERT_EQ(bridge.ServoExchange(sample)[0], 1.0) << "frame " << frame;
  }
  EXPECT_EQ(bridge.ServoExchange(sample)[0], 0.0);  // 50 frames without a new force
  EXPECT_EQ(bridge.num_watchdog_frames(), 1);
  bridge.Write(Eigen::Vector3d(0.5, 0, 0));  // the tick is back
  EXPECT_EQ(bridge.ServoExchange(sample)[0], 0.5);
}

TEST(HdServoBridge, ModelAndLimitsFromWhatTheDeviceReports) {
  EXPECT_EQ(DeviceModelFromHdModelType("PHANTOM Desktop"), DeviceModel::kDesktop);
  EXPECT_EQ(DeviceModelFromHdModelType("PHANTOM Omni"), DeviceModel::kOmni);
  EXPECT_EQ(DeviceModelFromHdModelType("Touch"), DeviceModel::kTouch);
  EXPECT_EQ(DeviceModelFromHdModelType("something new"), DeviceModel::kTouch);
  // A Touch reporting 3.0 N and 0.35 N/mm: the stricter values win.
  const DeviceLimits merged = MergeReportedLimits(LimitsFor(DeviceModel::kTouch), 3.0, 0.35);
  EXPECT_DOUBLE_EQ(merged.max_force, 3.0);
  EXPECT_DOUBLE_EQ(merged.max_stiffness, 350.0);
  // Reports beyond the table, or missing, leave the table.
  const DeviceLimits table = MergeReportedLimits(LimitsFor(DeviceModel::kTouch), 9.0, 0.0);
  EXPECT_DOUBLE_EQ(table.max_force, 3.3);
  EXPECT_DOUBLE_EQ(table.max_stiffness, 400.0);
}

// ---- CyberGrasp, without the SDK -------------------------------------------------------------

TEST(CyberGraspBridge, ConvertsTrackerUnitsAndEulerAnglesAndGrabsWithHysteresis) {
  CyberGraspCalibration calibration;  // inches, grab at 0.8 rad, release below 0.5 rad
  CyberGraspBridge bridge(calibration);
  HapticDevice& device = bridge;
  ASSERT_TRUE(device.Open().ok);
  DeviceState state;
  EXPECT_EQ(device.Read(state), DeviceFault::kNoData);
  CyberGraspSample sample;
  sample.time = 1.0;
  sample.tracker = {10.0, 0.0, -2.0, 0.0, 0.0, std::numbers::pi / 2};  // 90° yaw
  sample.finger_flexion = {0.0, 0.7, 0.7, 0.7, 0.7};  // not closed enough
  bridge.DeviceExchange(sample);
  ASSERT_EQ(device.Read(state), DeviceFault::kNone);
  EXPECT_NEAR(state.position.x(), 0.254, 1e-15);
  EXPECT_NEAR(state.position.z(), -0.0508, 1e-15);
  EXPECT_NEAR((state.orientation * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(),
              0.0, 1e-15);
  EXPECT_EQ(state.buttons, 0u);
  const auto step = [&](double t, double flexion, double x_inches) {
    sample.time = t;
    sample.tracker[0] = x_inches;
    sample.finger_flexion = {0.0, flexion, flexion, flexion, flexion};
    bridge.DeviceExchange(sample);
    device.Read(state);
    return state.buttons;
  };
  EXPECT_EQ(step(1.1, 0.85, 11.0), static_cast<std::uint32_t>(kButtonGrab));  // closes
  EXPECT_NEAR(state.velocity.x(), 0.0254 / 0.1, 1e-9);  // 1 inch in 0.1 s
  EXPECT_EQ(step(1.2, 0.6, 11.0), static_cast<std::uint32_t>(kButtonGrab));  // still held
  EXPECT_EQ(step(1.3, 0.45, 11.0), 0u);                                       // lets go
  EXPECT_EQ(step(1.4, 0.6, 11.0), 0u);                                        // not yet again
}

TEST(CyberGraspBridge, ForceMagnitudeBecomesTheSameLevelOnEveryFinger) {
  CyberGraspBridge bridge;
  HapticDevice& device = bridge;
  ASSERT_TRUE(device.Open().ok);
  CyberGraspSample sample;
  device.Write(Eigen::Vector3d(3.0, 0, 4.0));  // 5 N of the 12 N range
  std::array<double, 5> levels = bridge.DeviceExchange(sample);
  for (double level : levels) EXPECT_NEAR(level, 5.0 / 12.0, 1e-15);
  device.Write(Eigen::Vector3d(0, 0, 100.0));
  levels = bridge.DeviceExchange(sample);
  for (double level : levels) EXPECT_EQ(level, 1.0);
  device.Write(Eigen::Vector3d(0, std::nan(""), 0));
  levels = bridge.DeviceExchange(sample);
  for (double level : levels) EXPECT_EQ(level, 0.0);
  EXPECT_THROW(CyberGraspBridge(CyberGraspCalibration{0.01, 0.4, 0.5}), sim::InputError);
}

TEST(WorkspaceTransform, MapsDeviceToSceneAndForcesBack) {
  WorkspaceTransform w;
  w.scale = 5.0;
  w.offset = Eigen::Vector3d(0, 1.2, 0);
  w.rotation = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY()).matrix();
  w.Validate("test");
  // Device x → scene −z (a quarter turn about y), scaled by 5, then offset.
  const Eigen::Vector3d p = w.PositionToScene(Eigen::Vector3d(0.02, 0.01, 0));
  EXPECT_NEAR((p - Eigen::Vector3d(0, 1.25, -0.1)).norm(), 0.0, 1e-15);
  // Forces are rotated back, never scaled.
  const Eigen::Vector3d f = w.ForceToDevice(Eigen::Vector3d(0, 0, -2.0));
  EXPECT_NEAR((f - Eigen::Vector3d(2.0, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((w.DisplacementToDevice(Eigen::Vector3d(0, 0, -0.1)) -
               Eigen::Vector3d(0.02, 0, 0)).norm(), 0.0, 1e-15);
  w.scale = 0.0;
  EXPECT_THROW(w.Validate("test"), sim::InputError);
  // A scale of 1e300 put the tip 1e298 m away and was accepted; the bounds name the field.
  for (double scale : {1e-4, 1.001e3, 1e300}) {
    w.scale = scale;
    try {
      w.Validate("test", "--scale", "--offset");
      ADD_FAILURE() << scale;
    } catch (const sim::InputError& error) {
      EXPECT_NE(std::string(error.what()).find("--scale = "), std::string::npos) << error.what();
      EXPECT_NE(std::string(error.what()).find("0.001"), std::string::npos) << error.what();
    }
  }
  w.scale = WorkspaceTransform::kMaxScale;
  w.Validate("test");
  w.offset.z() = -1.0001e4;
  EXPECT_THROW(w.Validate("test"), sim::InputError);
  w.offset.z() = -1e4;
  w.Validate("test");
  w.scale = 1.0;
  w.rotation(0, 0) = 2.0;
  EXPECT_THROW(w.Validate("test"), sim::InputError);
}

}  // namespace
}  // namespace costume::haptics
