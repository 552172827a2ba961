#pragma once
/// @file
/// The GUI's mouse as a haptic device. The GUI thread maps the pointer to a 3D point (device
/// frame [m]; e.g. the pointer ray against a plane through the grab) and pushes it with the
/// button state; the tick reads the newest one. The hand-over is a lock-free single-slot mailbox
/// (TripleBuffer), so neither the GUI nor the tick ever waits for the other. A mouse renders no
/// force: the forces written are handed back to the GUI the same way, to be drawn.

#include <Eigen/Core>
#include <cstdint>

#include "haptic_server/device.h"
#include "haptic_server/lock_free.h"

namespace costume::haptics {

/// One pointer sample from the GUI.
struct MouseSample {
  /// GUI time of the event [s] (any monotonic origin).
  double time = 0.0;
  /// Pointer mapped to the device frame [m].
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  /// DeviceButton bits (left button → kButtonGrab, for instance).
  std::uint32_t buttons = 0;
  /// False once the pointer has left the 3D view: the device then reads kNoData with every
  /// button released, so a held grab ends and ForceSafety fades the force out.
  bool inside_view = true;
};

/// The mouse device. Producer side (Push, TakeForce): the GUI thread. Consumer side (Read,
/// Write): the tick.
class MouseDevice final : public HapticDevice {
 public:
  std::string name() const override { return "mouse"; }
  DeviceModel model() const override { return DeviceModel::kMouse; }
  DeviceStatus Open() override;
  DeviceStatus Close() override;
  /// The newest sample; velocity is the finite difference of the last two distinct samples.
  /// kNoData before the first Push and while the newest sample is outside the view (then the
  /// last position is held, velocity zero, no button pressed); a non-finite sample is refused
  /// (kNonFinite, previous kept).
  DeviceFault Read(DeviceState& state) override;
  /// Records `force` [N] for the GUI (TakeForce); nothing is rendered.
  DeviceFault Write(const Eigen::Vector3d& force) override;

  /// GUI thread: hands a new pointer sample to the tick. Never blocks; never allocates.
  void Push(const MouseSample& sample);
  /// GUI thread: the newest force written by the tick, if one arrived since the last call.
  bool TakeForce(Eigen::Vector3d& force);

 private:
  TripleBuffer<MouseSample> samples_;
  TripleBuffer<Eigen::Vector3d> forces_;
  bool open_ = false;
  bool has_sample_ = false;
  bool inside_view_ = true;
  DeviceState current_;
};

}  // namespace costume::haptics
