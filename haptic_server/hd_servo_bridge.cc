#include "haptic_server/hd_servo_bridge.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string>

namespace costume::haptics {

namespace {
constexpr double kMetresPerMillimetre = 1e-3;

bool ContainsNoCase(std::string_view text, std::string_view word) {
  const auto it = std::search(text.begin(), text.end(), word.begin(), word.end(),
                              [](char a, char b) {
                                return std::tolower(static_cast<unsigned char>(a)) ==
                                       std::tolower(static_cast<unsigned char>(b));
                              });
  return it != text.end();
}
}  // namespace

std::uint32_t ButtonsFromHd(int hd_buttons) {
  std::uint32_t buttons = 0;
  if (hd_buttons & kHdButton1) buttons |= kButtonGrab;
  if (hd_buttons & kHdButton2) buttons |= kButtonStretchRelief;
  return buttons;
}

DeviceState DeviceStateFromHd(const HdServoSample& sample) {
  DeviceState state;
  state.time = sample.time;
  for (int i = 0; i < 3; ++i) {
    state.position[i] = sample.position_mm[i] * kMetresPerMillimetre;
    state.velocity[i] = sample.velocity_mm_s[i] * kMetresPerMillimetre;
  }
  Eigen::Matrix3d rotation;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) rotation(row, col) = sample.transform[col * 4 + row];
  }
  state.orientation = Eigen::Quaterniond(rotation).normalized();
  state.buttons = ButtonsFromHd(sample.buttons);
  return state;
}

std::array<double, 3> HdForceCommand(const Eigen::Vector3d& force, double max_force) {
  Eigen::Vector3d f = force;
  ClampForce(f, max_force);
  return {f.x(), f.y(), f.z()};
}

DeviceModel DeviceModelFromHdModelType(std::string_view model_type) {
  if (ContainsNoCase(model_type, "desktop")) return DeviceModel::kDesktop;
  if (ContainsNoCase(model_type, "omni")) return DeviceModel::kOmni;
  return DeviceModel::kTouch;
}

DeviceLimits MergeReportedLimits(const DeviceLimits& table, double nominal_max_force,
                                 double nominal_max_stiffness_n_per_mm) {
  DeviceLimits merged = table;
  if (std::isfinite(nominal_max_force) && nominal_max_force > 0.0) {
    merged.max_force = std::min(merged.max_force, nominal_max_force);
  }
  const double reported_stiffness = nominal_max_stiffness_n_per_mm * 1e3;  // N/mm → N/m
  if (std::isfinite(reported_stiffness) && reported_stiffness > 0.0) {
    merged.max_stiffness = std::min(merged.max_stiffness, reported_stiffness);
  }
  return merged;
}

HdServoBridge::HdServoBridge(DeviceModel model) : model_(model), limits_(LimitsFor(model)) {}

DeviceStatus HdServoBridge::Open() {
  open_.store(true, std::memory_order_release);
  return DeviceStatus::Ok();
}

DeviceStatus HdServoBridge::Close() {
  open_.store(false, std::memory_order_release);
  return DeviceStatus::Ok();
}

DeviceFault HdServoBridge::Read(DeviceState& state) {
  if (!open_.load(std::memory_order_acquire)) return DeviceFault::kNotOpen;
  has_sample_ = samples_.Update() || has_sample_;
  if (!has_sample_) return DeviceFault::kNoData;
  const HdServoSample& sample = samples_.front();
  state = DeviceStateFromHd(sample);
  return sample.error ? DeviceFault::kCommunication : DeviceFault::kNone;
}

DeviceFault HdServoBridge::Write(const Eigen::Vector3d& force) {
  if (!open_.load(std::memory_order_acquire)) return DeviceFault::kNotOpen;
  forces_.back() = HdForceCommand(force, limits_.max_force);
  forces_.Publish();
  return force.allFinite() ? DeviceFault::kNone : DeviceFault::kNonFinite;
}

std::array<double, 3> HdServoBridge::ServoExchange(const HdServoSample& sample) {
  samples_.back() = sample;
  samples_.Publish();
  if (forces_.Update()) {
    servo_force_ = forces_.front();
    frames_since_force_ = 0;
  } else if (frames_since_force_ < kWatchdogFrames) {
    ++frames_since_force_;
  }
  const bool starved = frames_since_force_ >= kWatchdogFrames;
  if (starved) num_watchdog_frames_.fetch_add(1, std::memory_order_relaxed);
  if (starved || !open_.load(std::memory_order_acquire)) return {0.0, 0.0, 0.0};
  return servo_force_;
}

}  // namespace costume::haptics
