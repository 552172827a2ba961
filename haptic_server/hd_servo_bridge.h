#pragma once
/// @file
/// The device-independent half of the OpenHaptics device. The HD API runs its own 1 kHz servo
/// thread and calls our callback there (hdScheduleAsynchronous); the callback only copies the
/// device's values into an HdServoSample, calls HdServoBridge::ServoExchange and writes back
/// the force it returns. Everything else — units (the HD API speaks millimetres), button
/// mapping, the force clamp, a watchdog, and the hand-over to and from our tick through
/// lock-free mailboxes — lives here, where tests reach it through the HapticDevice interface
/// without the SDK. openhaptics_device.h adds the SDK calls (compiled only when it is found).

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstdint>
#include <string_view>

#include "haptic_server/device.h"
#include "haptic_server/lock_free.h"

namespace costume::haptics {

/// HD_DEVICE_BUTTON_1 and HD_DEVICE_BUTTON_2 as hd.h defines them (1 << 0, 1 << 1); the SDK
/// build static_asserts that they agree.
inline constexpr int kHdButton1 = 1 << 0;
inline constexpr int kHdButton2 = 1 << 1;

/// One servo frame as the HD API reports it, in its units.
struct HdServoSample {
  /// Servo clock [s] (monotonic).
  double time = 0.0;
  /// HD_CURRENT_POSITION [mm], device frame.
  std::array<double, 3> position_mm{};
  /// HD_CURRENT_VELOCITY [mm/s].
  std::array<double, 3> velocity_mm_s{};
  /// HD_CURRENT_TRANSFORM: 4×4 column-major, rotation of the stylus in the device frame,
  /// translation in mm (unused: position_mm is the tip).
  std::array<double, 16> transform{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  /// HD_CURRENT_BUTTONS bit mask.
  int buttons = 0;
  /// hdGetError reported a device error in this frame.
  bool error = false;
};

/// HD button bits to DeviceButton bits: button 1 (front) grabs, button 2 (rear) is stretch
/// relief; other buttons are ignored. Never throws; never allocates.
std::uint32_t ButtonsFromHd(int hd_buttons);

/// An HdServoSample in SI units and our conventions: mm → m, mm/s → m/s, rotation block of the
/// column-major transform → unit quaternion, buttons mapped. Never throws; never allocates.
DeviceState DeviceStateFromHd(const HdServoSample& sample);

/// The force for hdSetDoublev(HD_CURRENT_FORCE) [N]: `force` with non-finite components
/// replaced by zero and clamped to `max_force` in magnitude. Never throws; never allocates.
std::array<double, 3> HdForceCommand(const Eigen::Vector3d& force, double max_force);

/// The model from hdGetString(HD_DEVICE_MODEL_TYPE): strings containing "Desktop" → kDesktop,
/// "Omni" → kOmni, "Touch" → kTouch (case-insensitive); anything else → kTouch, the weakest.
DeviceModel DeviceModelFromHdModelType(std::string_view model_type);

/// The stricter of the table's limits and what the device reports (HD_NOMINAL_MAX_FORCE [N],
/// HD_NOMINAL_MAX_STIFFNESS [N/mm]); a reported value <= 0 or not finite is ignored.
DeviceLimits MergeReportedLimits(const DeviceLimits& table, double nominal_max_force,
                                 double nominal_max_stiffness_n_per_mm);

/// The bridge between an HD servo thread (producer of samples, consumer of forces) and our tick
/// (the reverse). Usable on its own as a test double: Open/Close only mark it open; the SDK
/// device overrides them.
class HdServoBridge : public HapticDevice {
 public:
  /// Servo frames without a new force from the tick after which the servo sends zero: 50 ms at
  /// the HD scheduler's 1 kHz (the same bound as a stale patch).
  static constexpr int kWatchdogFrames = 50;

  explicit HdServoBridge(DeviceModel model = DeviceModel::kTouch);

  std::string name() const override { return "HD servo bridge"; }
  DeviceModel model() const override { return model_; }
  DeviceLimits limits() const override { return limits_; }
  DeviceStatus Open() override;
  DeviceStatus Close() override;
  /// The newest servo sample in SI units. kNoData before the first; kCommunication while the
  /// servo reports an error (the state is still the newest sample).
  DeviceFault Read(DeviceState& state) override;
  /// Hands `force` [N] (device frame) to the servo thread, clamped to limits().max_force.
  DeviceFault Write(const Eigen::Vector3d& force) override;

  /// Servo thread: publishes `sample` and returns the force to send [N]: the newest from the
  /// tick, or zero when the bridge is closed or the tick has sent nothing for kWatchdogFrames.
  /// Never blocks; never allocates.
  std::array<double, 3> ServoExchange(const HdServoSample& sample);
  /// Servo frames in which the watchdog zeroed the force.
  std::int64_t num_watchdog_frames() const {
    return num_watchdog_frames_.load(std::memory_order_relaxed);
  }

 protected:
  void set_model(DeviceModel model) { model_ = model; }
  void set_limits(const DeviceLimits& limits) { limits_ = limits; }

 private:
  DeviceModel model_;
  DeviceLimits limits_;
  std::atomic<bool> open_{false};
  TripleBuffer<HdServoSample> samples_;
  TripleBuffer<std::array<double, 3>> forces_;
  bool has_sample_ = false;             // tick side
  std::array<double, 3> servo_force_{}; // servo side
  int frames_since_force_ = 0;          // servo side
  std::atomic<std::int64_t> num_watchdog_frames_{0};
};

}  // namespace costume::haptics
