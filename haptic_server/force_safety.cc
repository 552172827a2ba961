#include "haptic_server/force_safety.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sim_core/common/input_error.h"

namespace costume::haptics {

void ForceSafetyOptions::Validate(const std::string& what) const {
  sim::RequirePositive(what + ".limits.max_force", limits.max_force, "N");
  sim::RequirePositive(what + ".limits.max_stiffness", limits.max_stiffness, "N/m");
  sim::RequirePositive(what + ".ramp_time", ramp_time, "s");
  sim::RequirePositive(what + ".fade_time", fade_time, "s");
  sim::RequirePositive(what + ".stale_after", stale_after, "s");
  sim::RequireNonNegative(what + ".base_filter_time", base_filter_time, "s");
}

ForceSafety::ForceSafety(const ForceSafetyOptions& options) : options_(options) {
  options_.Validate("force safety");
}

void ForceSafety::Reset() {
  phase_ = gain_ = 0.0;
  was_stale_ = false;
  last_now_ = std::numeric_limits<double>::quiet_NaN();
  filtered_base_.setZero();
  flags_ = {};
  counters_ = {};
}

double ForceSafety::RampShape(double phase) {
  const double p = std::clamp(phase, 0.0, 1.0);
  return 0.5 * (1.0 - std::cos(std::numbers::pi * p));
}

Eigen::Vector3d ForceSafety::LimitStiffness(const SafetyInput& input) {
  Eigen::Vector3d following = input.force - input.base_force;
  const double allowed = options_.limits.max_stiffness * input.tip_displacement.norm();
  const double magnitude = following.norm();
  if (magnitude > allowed) {
    following *= magnitude > 0.0 ? allowed / magnitude : 0.0;
    flags_.stiffness_limited = true;
    ++counters_.num_stiffness_limited;
  }
  return following;
}

void ForceSafety::AdvancePhase(bool active, double dt, double elapsed) {
  // Phase steps are exact multiples of dt/T; snap the last sliver so zero really is zero.
  constexpr double kSnap = 1e-9;
  if (active) {
    // By the nominal period: after a stall of the loop the force must not jump up.
    phase_ = std::min(1.0, phase_ + dt / options_.ramp_time);
    if (phase_ > 1.0 - kSnap) phase_ = 1.0;
    flags_.ramping = phase_ < 1.0;
  } else {
    // By the time that passed: at normal priority on a loaded machine the 1 kHz loop skipped
    // ticks, and a fade counted in ticks still pushed 0.1 N 57 ms after the simulation's
    // last patch (grab_release_test), past the 50 ms promised.
    phase_ = std::max(0.0, phase_ - elapsed / options_.fade_time);
    if (phase_ < kSnap) phase_ = 0.0;
    flags_.fading = phase_ > 0.0;
  }
  gain_ = RampShape(phase_);
}

Eigen::Vector3d ForceSafety::Step(const SafetyInput& input, double dt) {
  flags_ = {};
  ++counters_.num_steps;
  const bool finite = input.force.allFinite() && input.base_force.allFinite() &&
                      input.tip_displacement.allFinite() && std::isfinite(input.now) &&
                      std::isfinite(input.last_patch_time) && std::isfinite(dt) && dt > 0.0;
  if (!finite) {
    flags_.non_finite = true;
    ++counters_.num_non_finite;
    phase_ = gain_ = 0.0;
    filtered_base_.setZero();
    return Eigen::Vector3d::Zero();
  }

  flags_.stale = input.now - input.last_patch_time > options_.stale_after;
  if (flags_.stale) ++counters_.num_stale_steps;
  if (flags_.stale && input.grab_active && !was_stale_) ++counters_.num_stale_episodes;
  was_stale_ = flags_.stale;

  // At zero gain there is nothing to smooth: start the filter at the current value so the
  // ramp alone shapes the onset.
  if (gain_ == 0.0 || options_.base_filter_time == 0.0) {
    filtered_base_ = input.base_force;
  } else {
    filtered_base_ += (1.0 - std::exp(-dt / options_.base_filter_time)) *
                      (input.base_force - filtered_base_);
  }
  const Eigen::Vector3d following = LimitStiffness(input);

  const double elapsed = std::isfinite(last_now_) ? std::max(dt, input.now - last_now_) : dt;
  last_now_ = input.now;
  AdvancePhase(input.grab_active && !flags_.stale, dt, elapsed);
  Eigen::Vector3d output = gain_ * (filtered_base_ + following);
  if (ClampForce(output, options_.limits.max_force)) {
    flags_.force_clamped = true;
    ++counters_.num_force_clamped;
  }
  return output;
}

}  // namespace costume::haptics
