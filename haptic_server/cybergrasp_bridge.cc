#include "haptic_server/cybergrasp_bridge.h"

#include <algorithm>
#include <cmath>

#include "sim_core/common/input_error.h"

namespace costume::haptics {

void CyberGraspCalibration::Validate(const std::string& what) const {
  sim::RequirePositive(what + ".tracker_unit", tracker_unit, "m");
  sim::RequirePositive(what + ".grab_open", grab_open, "rad");
  if (!(std::isfinite(grab_closed) && grab_closed > grab_open)) {
    throw sim::InputError(what + ".grab_closed = " + sim::FormatValue(grab_closed) +
                          " rad is not allowed: it must be finite and > grab_open = " +
                          sim::FormatValue(grab_open) + " rad");
  }
}

DeviceState DeviceStateFromCyberGrasp(const CyberGraspSample& sample,
                                      const CyberGraspCalibration& calibration,
                                      std::uint32_t previous_buttons) {
  DeviceState state;
  state.time = sample.time;
  state.position = calibration.tracker_unit *
                   Eigen::Vector3d(sample.tracker[0], sample.tracker[1], sample.tracker[2]);
  state.orientation = Eigen::AngleAxisd(sample.tracker[5], Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(sample.tracker[4], Eigen::Vector3d::UnitY()) *
                      Eigen::AngleAxisd(sample.tracker[3], Eigen::Vector3d::UnitX());
  double flexion = 0.0;
  for (int finger = 1; finger < 5; ++finger) flexion += sample.finger_flexion[finger];
  flexion /= 4.0;
  const bool was_grabbing = (previous_buttons & kButtonGrab) != 0;
  const bool grabbing = was_grabbing ? flexion > calibration.grab_open
                                     : flexion >= calibration.grab_closed;
  state.buttons = grabbing ? kButtonGrab : 0u;
  return state;
}

std::array<double, 5> CyberGraspForceLevels(const Eigen::Vector3d& force, double max_force) {
  std::array<double, 5> levels{};
  if (!force.allFinite() || !(max_force > 0.0)) return levels;
  levels.fill(std::clamp(force.norm() / max_force, 0.0, 1.0));
  return levels;
}

CyberGraspBridge::CyberGraspBridge(const CyberGraspCalibration& calibration)
    : calibration_(calibration) {
  calibration_.Validate("CyberGrasp calibration");
}

DeviceStatus CyberGraspBridge::Open() {
  open_.store(true, std::memory_order_release);
  return DeviceStatus::Ok();
}

DeviceStatus CyberGraspBridge::Close() {
  open_.store(false, std::memory_order_release);
  return DeviceStatus::Ok();
}

DeviceFault CyberGraspBridge::Read(DeviceState& state) {
  if (!open_.load(std::memory_order_acquire)) return DeviceFault::kNotOpen;
  DeviceFault fault = DeviceFault::kNone;
  if (samples_.Update()) {
    const CyberGraspSample& s = samples_.front();
    const DeviceState next = DeviceStateFromCyberGrasp(s, calibration_, current_.buttons);
    const double dt = next.time - current_.time;
    Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
    if (has_sample_ && dt > 0.0) velocity = (next.position - current_.position) / dt;
    current_ = next;
    current_.velocity = velocity;
    has_sample_ = true;
    if (s.error) fault = DeviceFault::kCommunication;
  }
  state = current_;
  return has_sample_ ? fault : DeviceFault::kNoData;
}

DeviceFault CyberGraspBridge::Write(const Eigen::Vector3d& force) {
  if (!open_.load(std::memory_order_acquire)) return DeviceFault::kNotOpen;
  levels_.back() = CyberGraspForceLevels(force, limits().max_force);
  levels_.Publish();
  return force.allFinite() ? DeviceFault::kNone : DeviceFault::kNonFinite;
}

std::array<double, 5> CyberGraspBridge::DeviceExchange(const CyberGraspSample& sample) {
  samples_.back() = sample;
  samples_.Publish();
  if (levels_.Update()) {
    device_levels_ = levels_.front();
    updates_since_levels_ = 0;
  } else if (updates_since_levels_ < kWatchdogUpdates) {
    ++updates_since_levels_;
  }
  if (updates_since_levels_ >= kWatchdogUpdates || !open_.load(std::memory_order_acquire)) {
    return {};
  }
  return device_levels_;
}

}  // namespace costume::haptics
