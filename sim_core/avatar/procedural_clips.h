#pragma once
/// @file
/// Built-in animation clips on the built-in humanoid's skeleton, made without any file:
/// stand, walk, run, jump, kick (basic) and a short dance (choreography). Each loops
/// without a jump: every joint angle is a periodic function of time sampled over exactly
/// one period.

#include <string>
#include <vector>

#include "sim_core/avatar/clip.h"

namespace costume::sim {

/// Names of the built-in clips: "stand", "walk", "run", "jump", "kick", "dance".
const std::vector<std::string>& BuiltInClipNames();

/// The built-in clip `name` for `skeleton` (normally MakeHumanoidSkeleton()), sampled at
/// 60 frames per second, looping. The joint angles assume rest frames aligned with the world
/// (as MakeHumanoidSkeleton's); drive any other skeleton through a Retargeter. Joints the
/// skeleton does not map stay at rest. Locomotion is in place (no net travel); the root's
/// height keeps the lower foot on the ground (its heel and toe estimated from the ankle's
/// rest height), except in the run's flight. Periods: stand 4 s, walk 1.1 s, run 0.7 s,
/// jump 1.6 s, kick 1.5 s (right leg), dance 4 s. Throws InputError listing the valid names
/// for an unknown one, or for a null skeleton.
Clip MakeBuiltInClip(const std::string& name, std::shared_ptr<const Skeleton> skeleton);

}  // namespace costume::sim
