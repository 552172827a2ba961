#include "haptic_server/haptic_tick.h"

namespace costume::haptics {

namespace {

ForceSafetyOptions WithLimits(ForceSafetyOptions options, const HapticDevice& device,
                              bool use_device_limits) {
  if (use_device_limits) options.limits = device.limits();
  return options;
}

std::array<double, 3> ToArray(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

HapticTick::HapticTick(HapticDevice& device, PatchMailbox& patches, OutgoingQueue& outgoing,
                       const WorkspaceTransform& workspace, ForceSafetyOptions safety,
                       bool use_device_limits)
    : device_(device),
      patches_(patches),
      outgoing_(outgoing),
      workspace_(workspace),
      safety_(WithLimits(safety, device, use_device_limits)) {
  workspace_.Validate("haptic tick workspace");
}

void HapticTick::Tick(const TickInfo& info) {
  ++counters_.num_ticks;
  const DeviceFault read_fault = device_.Read(state_);
  ++counters_.num_read_faults[static_cast<int>(read_fault)];

  // A new patch: its force at the capture point is fixed until the next one, compute it once.
  if (patches_.Update()) {
    ++counters_.num_patches;
    base_force_scene_ = FeedbackForce(patches_.front(), Eigen::Vector3d::Zero());
  }
  const HapticPatch& patch = patches_.front();
  const Eigen::Vector3d tip = workspace_.PositionToScene(state_.position);
  const Eigen::Vector3d displacement = tip - patch.centre;
  const Eigen::Vector3d feedback = FeedbackForce(patch, displacement);

  SafetyInput input;
  input.now = static_cast<double>(info.now) * 1e-9;
  input.last_patch_time = patch.sequence == 0 ? input.now - 1e9 : patch.arrival_time;
  input.grab_active = (state_.buttons & kButtonGrab) != 0 && patch.valid &&
                      patch.num_selected > 0 && patch.sequence != 0;
  input.base_force = workspace_.ForceToDevice(base_force_scene_);
  input.force = workspace_.ForceToDevice(feedback);
  input.tip_displacement = workspace_.DisplacementToDevice(displacement);
  device_force_ = safety_.Step(input, info.period);
  ++counters_.num_write_faults[static_cast<int>(device_.Write(device_force_))];

  OutgoingDeviceState out;
  out.time_ns = info.now;
  out.sequence = info.index;
  out.tip_position = ToArray(tip);
  out.tip_velocity = ToArray(workspace_.VelocityToScene(state_.velocity));
  const Eigen::Quaterniond orientation(workspace_.rotation *
                                       state_.orientation.toRotationMatrix());
  out.tip_orientation = {orientation.w(), orientation.x(), orientation.y(), orientation.z()};
  out.device_force = ToArray(device_force_);
  out.feedback_force = ToArray(feedback);
  out.buttons = state_.buttons;
  out.gain = safety_.gain();
  out.safety = safety_.flags();
  out.read_fault = read_fault;
  out.patch_sequence = patch.sequence;
  if (!outgoing_.TryPush(out)) ++counters_.num_dropped_outgoing;
}

}  // namespace costume::haptics
