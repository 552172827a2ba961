#pragma once
/// @file
/// Replays a recorded device log as a device: a session recorded from a Touch can be replayed
/// without the hardware (and deterministically, in tests).
///
/// Device log file: one sample per line, '#' comments, blank lines ignored, times increasing:
///
///     # time[s] x y z[m]  qw qx qy qz  vx vy vz[m/s]  buttons
///     0.000  0.01 0.02 0.03  1 0 0 0  0 0 0  1
///
/// Positions, orientations and velocities are device frame; buttons are DeviceButton bits.

#include <string>
#include <string_view>
#include <vector>

#include "haptic_server/device.h"

namespace costume::haptics {

/// A parsed device log: at least one sample, strictly increasing times.
struct DeviceLog {
  std::string source;
  std::vector<DeviceState> samples;
};

/// Parses device-log text; `source` names it in errors. Throws costume::sim::InputError naming
/// source, line, field, value and rule for: a line without exactly 12 fields, a field that is
/// not a finite number, a time not after the previous one, a quaternion whose norm is not 1
/// within 1e-3 (it is normalised otherwise), buttons not an integer in 0..3, no sample.
DeviceLog ParseDeviceLog(std::string_view text, const std::string& source);

/// Reads and parses a device log file (InputError also when it cannot be opened).
DeviceLog LoadDeviceLog(const std::string& path);

/// One line of the log format for `state` (no newline), with round-trip precision. For the
/// recorder on the I/O thread (allocates).
std::string FormatDeviceLogLine(const DeviceState& state);

/// Replays a DeviceLog. Playback time starts at the first sample's time and advances by
/// `period` per Read; Read returns the latest sample at or before it (held, not interpolated:
/// the replay feeds the tick exactly the states that were recorded). Write only keeps the force.
class LogPlaybackDevice final : public HapticDevice {
 public:
  /// Throws InputError for an empty log or a non-positive period [s].
  LogPlaybackDevice(DeviceLog log, double period = 1e-3);

  std::string name() const override { return "log playback '" + log_.source + "'"; }
  DeviceModel model() const override { return DeviceModel::kLogPlayback; }
  /// Opening (again) rewinds to the first sample.
  DeviceStatus Open() override;
  DeviceStatus Close() override;
  /// kEndOfData once playback time has passed the last sample (the last one is held).
  DeviceFault Read(DeviceState& state) override;
  DeviceFault Write(const Eigen::Vector3d& force) override;

  /// The last force written [N].
  const Eigen::Vector3d& last_force() const { return last_force_; }

 private:
  DeviceLog log_;
  double period_;
  bool open_ = false;
  std::size_t cursor_ = 0;
  std::int64_t num_reads_ = 0;
  Eigen::Vector3d last_force_ = Eigen::Vector3d::Zero();
};

}  // namespace costume::haptics
