#pragma once
/// @file
/// The device-independent half of the CyberGrasp device (VirtualHand SDK). A CyberGrasp
/// pulls the five fingers back through tendons: it renders one unidirectional force per
/// finger, in 0..1 of its maximum (vhtCyberGrasp::setForce), and nothing on the arm. The hand's
/// position comes from a 6-DOF tracker (vhtTracker / vht6DofDevice: x, y, z in the tracker's
/// units, then ZYX Euler angles), the grab from how far the glove's fingers are closed.
/// cybergrasp_device.h runs the SDK calls on its own thread (the VHT calls go over the network
/// to the device manager and may block) and passes its values through CyberGraspBridge, which
/// hands them to and from the tick without locks. Everything here is tested without the SDK.
///
/// Force mapping (our choice, documented): the cloth's pull on the hand has no arm to act on,
/// so its magnitude becomes grip resistance: every finger gets ‖F‖ / max_force of its range,
/// clamped to [0, 1] — the designer feels the cloth's tension as fingers held open.

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstdint>

#include "haptic_server/device.h"
#include "haptic_server/lock_free.h"

namespace costume::haptics {

/// One update of glove, tracker and grasp as the SDK reports it.
struct CyberGraspSample {
  /// [s], monotonic.
  double time = 0.0;
  /// vht6DofDevice::getRawData(xPos, yPos, zPos, xAngle, yAngle, zAngle): position in tracker
  /// units, ZYX Euler angles [rad] (vht6DofDevice::ZYXEuler).
  std::array<double, 6> tracker{};
  /// Flexion of each finger, thumb to pinky [rad]: the mean of its glove joint angles.
  std::array<double, 5> finger_flexion{};
  /// The SDK threw or reported a lost connection during this update.
  bool error = false;
};

/// Calibration of the mapping from SDK values to a DeviceState.
struct CyberGraspCalibration {
  /// Metres per tracker unit (> 0): 0.0254 for trackers reporting inches, 0.01 for cm. Check
  /// the device manager's tracker configuration.
  double tracker_unit = 0.0254;
  /// Mean flexion of the four fingers (thumb excluded) above which the hand grabs [rad], and
  /// below which it lets go (hysteresis, so a trembling hand does not chatter).
  double grab_closed = 0.8;
  double grab_open = 0.5;
  /// Throws costume::sim::InputError unless tracker_unit > 0 and 0 < grab_open < grab_closed.
  void Validate(const std::string& what) const;
};

/// The tip (hand) state: position · tracker_unit [m], orientation Rz·Ry·Rx from the Euler
/// angles, grab from the finger flexion with hysteresis against `previous_buttons`. Velocity is
/// left zero (the bridge differentiates). Never throws; never allocates.
DeviceState DeviceStateFromCyberGrasp(const CyberGraspSample& sample,
                                      const CyberGraspCalibration& calibration,
                                      std::uint32_t previous_buttons);

/// Per-finger force levels for vhtCyberGrasp::setForce: ‖force‖ / max_force clamped to [0, 1]
/// for all five; zero for a non-finite force. Never throws; never allocates.
std::array<double, 5> CyberGraspForceLevels(const Eigen::Vector3d& force, double max_force);

/// The bridge between the SDK thread and the tick; usable alone as a test double (Open/Close
/// only mark it open).
class CyberGraspBridge : public HapticDevice {
 public:
  /// Throws InputError for a bad calibration.
  explicit CyberGraspBridge(const CyberGraspCalibration& calibration = {});

  std::string name() const override { return "CyberGrasp bridge"; }
  DeviceModel model() const override { return DeviceModel::kCyberGrasp; }
  DeviceStatus Open() override;
  DeviceStatus Close() override;
  /// Newest sample as a DeviceState; velocity by finite difference of successive samples.
  /// kNoData before the first; kCommunication when the SDK thread reported an error.
  DeviceFault Read(DeviceState& state) override;
  /// Hands the finger levels for `force` [N] to the SDK thread.
  DeviceFault Write(const Eigen::Vector3d& force) override;

  /// Updates without new levels from the tick after which the SDK thread sends zero.
  static constexpr int kWatchdogUpdates = 50;

  /// SDK thread: publishes `sample`, returns the finger levels to send: the newest from the
  /// tick; zero when closed or when the tick has sent nothing for kWatchdogUpdates updates.
  std::array<double, 5> DeviceExchange(const CyberGraspSample& sample);

 private:
  CyberGraspCalibration calibration_;
  std::atomic<bool> open_{false};
  TripleBuffer<CyberGraspSample> samples_;
  TripleBuffer<std::array<double, 5>> levels_;
  bool has_sample_ = false;           // tick side
  DeviceState current_;               // tick side
  std::array<double, 5> device_levels_{};  // SDK side
  int updates_since_levels_ = 0;           // SDK side
};

}  // namespace costume::haptics
