#pragma once
/// @file
/// A device without hardware, for tests and demos: a scripted trajectory (a small text file of
/// times, target positions and button states) that a virtual hand follows through a spring and
/// a damper; the force written back to the device acts on that hand, so feedback moves it as it
/// would move a user's hand.
///
/// Trajectory file, one keyframe per line, '#' starts a comment, blank lines are ignored:
///
///     # time [s]   x [m]   y [m]   z [m]   buttons (DeviceButton bits, 0..3)
///     0.0          0.0     0.0     0.0     0
///     0.5          0.0     0.0     0.0     1
///     1.5          0.10    0.0     0.0     1
///
/// Times are non-decreasing. Between keyframes the target moves linearly; a keyframe that
/// repeats the previous time makes a step (the later line wins from that time on). Buttons
/// hold the value of the latest keyframe at or before the time. Positions are device frame,
/// each within ±kMaxDeviceCoordinate (10 m).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "haptic_server/device.h"

namespace costume::haptics {

/// One line of a trajectory file.
struct TrajectoryKeyframe {
  /// [s] >= 0.
  double time = 0.0;
  /// Target tip position, device frame [m].
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  /// DeviceButton bits.
  std::uint32_t buttons = 0;
};

/// A scripted trajectory: at least one keyframe, times non-decreasing.
struct Trajectory {
  /// Where it came from, for messages (a path, or a name for text given directly).
  std::string source;
  std::vector<TrajectoryKeyframe> keyframes;

  /// Target position [m] and buttons at time `t` [s]: linear between keyframes, held before the
  /// first and after the last. O(log n). Never throws; never allocates.
  void Sample(double t, Eigen::Vector3d& position, std::uint32_t& buttons) const;
  /// Time of the last keyframe [s].
  double end_time() const { return keyframes.back().time; }
};

/// Parses trajectory text. `source` names it in errors. Throws costume::sim::InputError naming
/// source, line, field, the value found and what is allowed, for: a line without exactly five
/// fields; a field that is not a number; a non-finite number; a negative time or one before the
/// previous line's; buttons that are not an integer in 0..3; no keyframe at all.
Trajectory ParseTrajectory(std::string_view text, const std::string& source);

/// Reads and parses a trajectory file. Throws InputError as ParseTrajectory, and when the file
/// cannot be opened (naming the path).
Trajectory LoadTrajectory(const std::string& path);

/// The virtual hand: mass, and the spring and damper that pull it towards the target.
/// m ẍ = k (target − x) − c ẋ + F, with F the force written to the device.
struct VirtualHand {
  /// [kg] > 0.
  double mass = 0.2;
  /// [N/m] > 0. With the default mass: ω = √(k/m) ≈ 31.6 rad/s (5 Hz), a hand-like response.
  double stiffness = 200.0;
  /// [N·s/m] >= 0. Default: damping ratio ζ = c / (2√(km)) ≈ 0.7.
  double damping = 8.85;
  /// Throws InputError unless mass and stiffness are > 0 and damping >= 0 (all finite).
  void Validate(const std::string& what) const;
};

/// The simulated device. Time advances by one `period` per Write (one tick = Read, compute,
/// Write); a Write integrates the hand over that period (classic RK4, target and force held
/// constant over the period) and moves the device clock on.
class SimulatedDevice final : public HapticDevice {
 public:
  /// Throws InputError for a bad hand or a non-positive period [s]. The hand starts at rest at
  /// the first keyframe's position.
  SimulatedDevice(Trajectory trajectory, const VirtualHand& hand = {}, double period = 1e-3);

  std::string name() const override { return "simulated '" + trajectory_.source + "'"; }
  DeviceModel model() const override { return DeviceModel::kSimulated; }
  DeviceStatus Open() override;
  DeviceStatus Close() override;
  /// The hand's state now; kEndOfData (state still valid) once past the last keyframe.
  DeviceFault Read(DeviceState& state) override;
  /// Applies `force` [N] to the hand for one period and advances time.
  DeviceFault Write(const Eigen::Vector3d& force) override;

  /// Device clock [s].
  double time() const { return time_; }
  const Eigen::Vector3d& hand_position() const { return position_; }
  const Eigen::Vector3d& hand_velocity() const { return velocity_; }
  /// The last force applied to the hand (after the device's own clamp) [N].
  const Eigen::Vector3d& applied_force() const { return applied_force_; }

 private:
  Trajectory trajectory_;
  VirtualHand hand_;
  double period_;
  bool open_ = false;
  double time_ = 0.0;
  Eigen::Vector3d position_;
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d applied_force_ = Eigen::Vector3d::Zero();
};

}  // namespace costume::haptics
