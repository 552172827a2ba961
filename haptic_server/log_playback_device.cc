#include "haptic_server/log_playback_device.h"

#include <charconv>
#include <cmath>

#include "haptic_server/text_records.h"
#include "sim_core/common/input_error.h"

namespace costume::haptics {

DeviceLog ParseDeviceLog(std::string_view text, const std::string& source) {
  DeviceLog log;
  log.source = source;
  ParseRecords(
      text, source, {"time", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "buttons"},
      [&](int line, const std::vector<double>& v) {
        if (!log.samples.empty() && !(v[0] > log.samples.back().time)) {
          throw sim::InputError(RecordErrorPrefix(source, line, "time", v[0]) +
                                "[s] is not after the previous sample's " +
                                sim::FormatValue(log.samples.back().time) +
                                " s: times must increase");
        }
        RequirePositionWithin(source, line, v, 1, kMaxDeviceCoordinate);
        Eigen::Quaterniond q(v[4], v[5], v[6], v[7]);
        if (std::abs(q.norm() - 1.0) > 1e-3) {
          throw sim::InputError(RecordErrorPrefix(source, line, "qw", v[4]) +
                                "starts a quaternion of norm " + sim::FormatValue(q.norm()) +
                                ": (qw qx qy qz) must be a unit quaternion within 1e-3");
        }
        if (v[11] != std::floor(v[11]) || v[11] < 0 || v[11] > 3) {
          throw sim::InputError(RecordErrorPrefix(source, line, "buttons", v[11]) +
                                "is not allowed: it must be an integer in 0..3");
        }
        DeviceState s;
        s.time = v[0];
        s.position = Eigen::Vector3d(v[1], v[2], v[3]);
        s.orientation = q.normalized();
        s.velocity = Eigen::Vector3d(v[8], v[9], v[10]);
        s.buttons = static_cast<std::uint32_t>(v[11]);
        log.samples.push_back(s);
      });
  if (log.samples.empty()) {
    throw sim::InputError(source + ": no sample found: a device log needs at least one line "
                          "'time x y z qw qx qy qz vx vy vz buttons'");
  }
  return log;
}

DeviceLog LoadDeviceLog(const std::string& path) {
  return ParseDeviceLog(ReadTextFile(path, "device log"), path);
}

std::string FormatDeviceLogLine(const DeviceState& s) {
  const double values[11] = {s.time,           s.position.x(),   s.position.y(),
                             s.position.z(),   s.orientation.w(), s.orientation.x(),
                             s.orientation.y(), s.orientation.z(), s.velocity.x(),
                             s.velocity.y(),   s.velocity.z()};
  std::string line;
  char buffer[32];
  for (double v : values) {
    // Shortest round-trip form: a replay reads back exactly the recorded doubles.
    const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
    line.append(buffer, result.ptr);
    line += ' ';
  }
  line += std::to_string(s.buttons);
  return line;
}

LogPlaybackDevice::LogPlaybackDevice(DeviceLog log, double period)
    : log_(std::move(log)), period_(period) {
  if (log_.samples.empty()) {
    throw sim::InputError("log playback '" + log_.source + "': the log has no sample");
  }
  sim::RequirePositive("log playback '" + log_.source + "' period", period_, "s");
}

DeviceStatus LogPlaybackDevice::Open() {
  open_ = true;
  cursor_ = 0;
  num_reads_ = 0;
  return DeviceStatus::Ok();
}

DeviceStatus LogPlaybackDevice::Close() {
  open_ = false;
  return DeviceStatus::Ok();
}

DeviceFault LogPlaybackDevice::Read(DeviceState& state) {
  if (!open_) return DeviceFault::kNotOpen;
  // Times as start + k·period (not a running sum) so rounding never drifts.
  const double now = log_.samples.front().time + static_cast<double>(num_reads_++) * period_;
  // Half a nanosecond of slack: a sample recorded at exactly a tick's time belongs to it.
  while (cursor_ + 1 < log_.samples.size() && log_.samples[cursor_ + 1].time <= now + 5e-10) {
    ++cursor_;
  }
  state = log_.samples[cursor_];
  const bool past_end = cursor_ + 1 == log_.samples.size() && now > log_.samples.back().time;
  return past_end ? DeviceFault::kEndOfData : DeviceFault::kNone;
}

DeviceFault LogPlaybackDevice::Write(const Eigen::Vector3d& force) {
  if (!open_) return DeviceFault::kNotOpen;
  last_force_ = force;
  return force.allFinite() ? DeviceFault::kNone : DeviceFault::kNonFinite;
}

}  // namespace costume::haptics
