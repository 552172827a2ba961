#pragma once
/// @file
/// One tick of the haptic server, device-independent: read the device, take the newest patch,
/// compute the feedback at the tip, pass it through ForceSafety, write it to the device, and
/// queue the outgoing device state for the I/O thread (which publishes it; nothing is published
/// from the tick). Never allocates, locks or throws once constructed.

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "haptic_server/device.h"
#include "haptic_server/force_safety.h"
#include "haptic_server/grab_forces.h"
#include "haptic_server/haptic_loop.h"
#include "haptic_server/lock_free.h"

namespace costume::haptics {

/// What the tick hands to the I/O thread each tick (plain data; becomes the device-state LCM
/// message there). Scene frame unless said otherwise.
struct OutgoingDeviceState {
  /// Loop clock at the tick [ns].
  std::int64_t time_ns = 0;
  /// Tick number.
  std::int64_t sequence = 0;
  /// Tip position [m] and velocity [m/s], scene frame.
  std::array<double, 3> tip_position{};
  std::array<double, 3> tip_velocity{};
  /// Tip orientation (w, x, y, z), unit quaternion rotating tip axes into the scene frame.
  std::array<double, 4> tip_orientation{1.0, 0.0, 0.0, 0.0};
  /// The force sent to the device [N], device frame, after ForceSafety.
  std::array<double, 3> device_force{};
  /// The unfiltered feedback at the tip [N], scene frame (for the GUI and logs).
  std::array<double, 3> feedback_force{};
  /// DeviceButton bits.
  std::uint32_t buttons = 0;
  /// ForceSafety's ramp gain in [0, 1] and flags of this tick.
  double gain = 0.0;
  SafetyFlags safety;
  /// The device's Read fault of this tick.
  DeviceFault read_fault = DeviceFault::kNone;
  /// Sequence of the patch in use (0: none yet).
  std::uint64_t patch_sequence = 0;
};

/// The outgoing queue: 256 ticks of slack for the I/O thread.
using OutgoingQueue = SpscQueue<OutgoingDeviceState, 256>;
/// The incoming patch mailbox (I/O thread fills back(), PreparePatch, Publish).
using PatchMailbox = TripleBuffer<HapticPatch>;

/// Counters of HapticTick (tick thread only; read them when the loop is stopped or accept a
/// torn snapshot).
struct HapticTickCounters {
  std::uint64_t num_ticks = 0;
  std::uint64_t num_patches = 0;
  /// Outgoing states dropped because the I/O thread fell behind. Remedy: a faster I/O thread.
  std::uint64_t num_dropped_outgoing = 0;
  /// Read faults by DeviceFault value; Write faults likewise.
  std::array<std::uint64_t, 6> num_read_faults{};
  std::array<std::uint64_t, 6> num_write_faults{};
};

/// The tick. Holds references to the device, the patch mailbox and the outgoing queue, which
/// must outlive it.
class HapticTick final : public TickHandler {
 public:
  /// `workspace` maps the device into the scene (validated; throws InputError); `safety`
  /// options take their limits from device.limits() when `use_device_limits` is true.
  HapticTick(HapticDevice& device, PatchMailbox& patches, OutgoingQueue& outgoing,
             const WorkspaceTransform& workspace, ForceSafetyOptions safety,
             bool use_device_limits = true);

  /// Never allocates; never throws.
  void Tick(const TickInfo& info) override;

  const HapticTickCounters& counters() const { return counters_; }
  const ForceSafety& safety() const { return safety_; }
  const DeviceState& device_state() const { return state_; }
  /// The force sent on the last tick [N], device frame.
  const Eigen::Vector3d& last_device_force() const { return device_force_; }

 private:
  HapticDevice& device_;
  PatchMailbox& patches_;
  OutgoingQueue& outgoing_;
  WorkspaceTransform workspace_;
  ForceSafety safety_;
  DeviceState state_;
  Eigen::Vector3d base_force_scene_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d device_force_ = Eigen::Vector3d::Zero();
  HapticTickCounters counters_;
};

}  // namespace costume::haptics
