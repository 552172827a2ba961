#include "haptic_server/simulated_device.h"

#include <algorithm>
#include <cmath>

#include "haptic_server/text_records.h"
#include "sim_core/common/input_error.h"

namespace costume::haptics {

void Trajectory::Sample(double t, Eigen::Vector3d& position, std::uint32_t& buttons) const {
  // First keyframe strictly after t; the one before it is the latest at or before t (for
  // repeated times that is the later line, which makes a step).
  const auto after = std::upper_bound(
      keyframes.begin(), keyframes.end(), t,
      [](double time, const TrajectoryKeyframe& k) { return time < k.time; });
  if (after == keyframes.begin()) {
    position = keyframes.front().position;
    buttons = keyframes.front().buttons;
    return;
  }
  const TrajectoryKeyframe& before = *(after - 1);
  buttons = before.buttons;
  if (after == keyframes.end()) {
    position = before.position;
    return;
  }
  const double s = (t - before.time) / (after->time - before.time);
  position = before.position + s * (after->position - before.position);
}

Trajectory ParseTrajectory(std::string_view text, const std::string& source) {
  Trajectory trajectory;
  trajectory.source = source;
  ParseRecords(text, source, {"time", "x", "y", "z", "buttons"},
               [&](int line, const std::vector<double>& v) {
                 if (v[0] < 0.0) {
                   throw sim::InputError(RecordErrorPrefix(source, line, "time", v[0]) +
                                         "[s] is not allowed: it must be >= 0");
                 }
                 if (!trajectory.keyframes.empty() && v[0] < trajectory.keyframes.back().time) {
                   throw sim::InputError(
                       RecordErrorPrefix(source, line, "time", v[0]) +
                       "[s] is before the previous keyframe's " +
                       sim::FormatValue(trajectory.keyframes.back().time) +
                       " s: times must not decrease");
                 }
                 RequirePositionWithin(source, line, v, 1, kMaxDeviceCoordinate);
                 if (v[4] != std::floor(v[4]) || v[4] < 0 || v[4] > 3) {
                   throw sim::InputError(RecordErrorPrefix(source, line, "buttons", v[4]) +
                                         "is not allowed: it must be an integer in 0..3 "
                                         "(bit 0 grab, bit 1 stretch relief)");
                 }
                 trajectory.keyframes.push_back(
                     {v[0], Eigen::Vector3d(v[1], v[2], v[3]), static_cast<std::uint32_t>(v[4])});
               });
  if (trajectory.keyframes.empty()) {
    throw sim::InputError(source + ": no keyframe found: a trajectory needs at least one line "
                          "'time x y z buttons'");
  }
  return trajectory;
}

Trajectory LoadTrajectory(const std::string& path) {
  return ParseTrajectory(ReadTextFile(path, "trajectory file"), path);
}

void VirtualHand::Validate(const std::string& what) const {
  sim::RequirePositive(what + ".mass", mass, "kg");
  sim::RequirePositive(what + ".stiffness", stiffness, "N/m");
  sim::RequireNonNegative(what + ".damping", damping, "N·s/m");
}

SimulatedDevice::SimulatedDevice(Trajectory trajectory, const VirtualHand& hand, double period)
    : trajectory_(std::move(trajectory)), hand_(hand), period_(period) {
  if (trajectory_.keyframes.empty()) {
    throw sim::InputError("simulated device '" + trajectory_.source + "': empty trajectory");
  }
  hand_.Validate("simulated device '" + trajectory_.source + "' hand");
  sim::RequirePositive("simulated device '" + trajectory_.source + "' period", period_, "s");
  position_ = trajectory_.keyframes.front().position;
}

DeviceStatus SimulatedDevice::Open() {
  open_ = true;
  return DeviceStatus::Ok();
}

DeviceStatus SimulatedDevice::Close() {
  open_ = false;
  applied_force_.setZero();
  return DeviceStatus::Ok();
}

DeviceFault SimulatedDevice::Read(DeviceState& state) {
  if (!open_) return DeviceFault::kNotOpen;
  Eigen::Vector3d target;
  state.time = time_;
  state.position = position_;
  state.velocity = velocity_;
  state.orientation.setIdentity();
  trajectory_.Sample(time_, target, state.buttons);
  return time_ > trajectory_.end_time() ? DeviceFault::kEndOfData : DeviceFault::kNone;
}

DeviceFault SimulatedDevice::Write(const Eigen::Vector3d& force) {
  if (!open_) return DeviceFault::kNotOpen;
  const bool finite = force.allFinite();
  applied_force_ = force;
  ClampForce(applied_force_, limits().max_force);
  Eigen::Vector3d target;
  std::uint32_t buttons = 0;
  trajectory_.Sample(time_, target, buttons);
  // Classic RK4 on the linear hand, target and force held over the period.
  const double m = hand_.mass, k = hand_.stiffness, c = hand_.damping, h = period_;
  const auto accel = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& v) {
    return Eigen::Vector3d((k * (target - x) - c * v + applied_force_) / m);
  };
  const Eigen::Vector3d x0 = position_, v0 = velocity_;
  const Eigen::Vector3d a1 = accel(x0, v0);
  const Eigen::Vector3d x2 = x0 + 0.5 * h * v0, v2 = v0 + 0.5 * h * a1;
  const Eigen::Vector3d a2 = accel(x2, v2);
  const Eigen::Vector3d x3 = x0 + 0.5 * h * v2, v3 = v0 + 0.5 * h * a2;
  const Eigen::Vector3d a3 = accel(x3, v3);
  const Eigen::Vector3d x4 = x0 + h * v3, v4 = v0 + h * a3;
  const Eigen::Vector3d a4 = accel(x4, v4);
  position_ = x0 + h / 6.0 * (v0 + 2.0 * v2 + 2.0 * v3 + v4);
  velocity_ = v0 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
  time_ += period_;
  return finite ? DeviceFault::kNone : DeviceFault::kNonFinite;
}

}  // namespace costume::haptics
