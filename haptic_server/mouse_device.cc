#include "haptic_server/mouse_device.h"

#include <cmath>

namespace costume::haptics {

DeviceStatus MouseDevice::Open() {
  open_ = true;
  return DeviceStatus::Ok();
}

DeviceStatus MouseDevice::Close() {
  open_ = false;
  return DeviceStatus::Ok();
}

void MouseDevice::Push(const MouseSample& sample) {
  samples_.back() = sample;
  samples_.Publish();
}

bool MouseDevice::TakeForce(Eigen::Vector3d& force) {
  if (!forces_.Update()) return false;
  force = forces_.front();
  return true;
}

DeviceFault MouseDevice::Read(DeviceState& state) {
  if (!open_) return DeviceFault::kNotOpen;
  DeviceFault fault = DeviceFault::kNone;
  if (samples_.Update()) {
    const MouseSample& s = samples_.front();
    if (!s.inside_view) {  // its position means nothing: hold the last one
      inside_view_ = false;
      current_.velocity.setZero();
      current_.buttons = 0;
    } else if (!s.position.allFinite() || !std::isfinite(s.time)) {
      fault = DeviceFault::kNonFinite;
    } else {
      inside_view_ = true;
      const double dt = s.time - current_.time;
      if (has_sample_ && dt > 0.0) current_.velocity = (s.position - current_.position) / dt;
      current_.time = s.time;
      current_.position = s.position;
      current_.buttons = s.buttons;
      has_sample_ = true;
    }
  }
  state = current_;
  if (!has_sample_ || !inside_view_) return DeviceFault::kNoData;
  return fault;
}

DeviceFault MouseDevice::Write(const Eigen::Vector3d& force) {
  if (!open_) return DeviceFault::kNotOpen;
  forces_.back() = force;
  forces_.Publish();
  return force.allFinite() ? DeviceFault::kNone : DeviceFault::kNonFinite;
}

}  // namespace costume::haptics
