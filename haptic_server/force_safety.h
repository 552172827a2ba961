#pragma once
/// @file
/// What stands between the computed feedback and the motors (STYLE.md §3: flags and counters,
/// never exceptions). Works in the *device* frame, where the limits are defined. In order:
///
/// 1. Not finite: any non-finite input (force, displacement, time) zeroes the output at once,
///    resets the ramp and counts. Remedy: none needed, the ramp restarts on finite input; a
///    persistent count points at the simulation or the device driver.
/// 2. Stiffness limit: the feedback is split into the force at the patch's capture point,
///    F(0), and the part that follows the tip, F(u) − F(0). The latter is limited in magnitude
///    to max_stiffness · ‖u‖ (u: the tip's device-frame displacement since the patch was
///    captured), so the rendered stiffness, the change of force per tip displacement, never
///    exceeds the device's. F(0) jumps at 60 Hz when patches arrive; it is low-passed with a
///    time constant of one simulation frame so those jumps are not felt as clicks.
/// 3. Ramp: the gain rises over ramp_time (200 ms) after a grab starts or after patches resume,
///    as a raised cosine of the phase φ ∈ [0, 1]: gain = (1 − cos πφ) / 2 (C¹: no jerk at
///    either end).
/// 4. Fade: when the grab ends, or patches are stale (none for more than stale_after =
///    1.5 frames at 60 Hz = 25 ms), φ falls to zero over fade_time (25 ms) of time, however
///    many ticks the loop skipped. The force is thus zero at most stale_after + fade_time =
///    50 ms after the last patch arrived (plus the tick that finds the deadline passed).
/// 5. Clamp: the magnitude is scaled down to max_force, keeping the direction.

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>

#include "haptic_server/device.h"

namespace costume::haptics {

/// Tuning of ForceSafety. Validate() throws costume::sim::InputError naming the field.
struct ForceSafetyOptions {
  /// The device's limits (LimitsFor(model) or what the device reports).
  DeviceLimits limits;
  /// Time to ramp the force in after a grab starts or patches resume [s] > 0.
  double ramp_time = 0.2;
  /// Time to fade the force from full to zero [s] > 0.
  double fade_time = 0.025;
  /// A patch older than this is stale [s] > 0: 1.5 frames at 60 Hz.
  double stale_after = 1.5 / 60.0;
  /// Time constant of the low-pass on the patch-to-patch force F(0) [s] >= 0 (0: no filter).
  double base_filter_time = 1.0 / 60.0;
  /// Throws InputError unless every field is finite and in range; `what` names the owner.
  void Validate(const std::string& what) const;
};

/// One tick's input, device frame.
struct SafetyInput {
  /// Loop time now [s].
  double now = 0.0;
  /// Loop time the newest patch arrived [s].
  double last_patch_time = 0.0;
  /// The grab button is held and the patch selects particles.
  bool grab_active = false;
  /// Feedback at the patch's capture point, F(0) [N].
  Eigen::Vector3d base_force = Eigen::Vector3d::Zero();
  /// Feedback at the current tip, F(u) [N].
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  /// Tip displacement since the patch's capture, u [m].
  Eigen::Vector3d tip_displacement = Eigen::Vector3d::Zero();
};

/// What ForceSafety did on the last Step; each flag names its remedy.
struct SafetyFlags {
  /// The output was scaled down to max_force. Remedy: lower F_h or the grab radius.
  bool force_clamped = false;
  /// The tip-following part was limited to max_stiffness. Remedy: softer cloth, smaller
  /// workspace scale, or a device with a higher stiffness limit.
  bool stiffness_limited = false;
  /// The gain is rising (grab start or patches resumed).
  bool ramping = false;
  /// The gain is falling (grab released, patches stale).
  bool fading = false;
  /// No patch for more than stale_after. Remedy: is the simulation server running?
  bool stale = false;
  /// An input was not finite; the output is zero. Remedy: see the simulation's status.
  bool non_finite = false;
};

/// Totals since construction or Reset().
struct SafetyCounters {
  std::uint64_t num_steps = 0;
  std::uint64_t num_force_clamped = 0;
  std::uint64_t num_stiffness_limited = 0;
  std::uint64_t num_stale_steps = 0;
  /// Times the patches went stale during a grab.
  std::uint64_t num_stale_episodes = 0;
  std::uint64_t num_non_finite = 0;
};

/// The safety filter. One instance per device, stepped once per tick.
class ForceSafety {
 public:
  /// Throws InputError for invalid options.
  explicit ForceSafety(const ForceSafetyOptions& options);

  /// The force to send to the device [N], device frame, for a tick of length `dt` [s] > 0
  /// (the loop's nominal period). A fade advances by the time since the previous step's
  /// `input.now` when that is longer: ticks the loop skipped must not put off the zero force.
  /// Never throws; never allocates.
  Eigen::Vector3d Step(const SafetyInput& input, double dt);

  /// The ramp gain of the last Step, in [0, 1].
  double gain() const { return gain_; }
  const SafetyFlags& flags() const { return flags_; }
  const SafetyCounters& counters() const { return counters_; }
  const ForceSafetyOptions& options() const { return options_; }
  /// Back to zero gain and zero counters.
  void Reset();

  /// The ramp shape: (1 − cos πφ) / 2 for φ clamped to [0, 1].
  static double RampShape(double phase);

 private:
  Eigen::Vector3d LimitStiffness(const SafetyInput& input);
  void AdvancePhase(bool active, double dt, double elapsed);

  ForceSafetyOptions options_;
  double phase_ = 0.0;
  double gain_ = 0.0;
  bool was_stale_ = false;
  /// The previous step's input.now [s]; NaN before the first.
  double last_now_ = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d filtered_base_ = Eigen::Vector3d::Zero();
  SafetyFlags flags_;
  SafetyCounters counters_;
};

}  // namespace costume::haptics
