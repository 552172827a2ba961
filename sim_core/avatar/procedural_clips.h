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
/// 60 frames per second. Throws InputError listing the valid names for an unknown one.
Clip MakeBuiltInClip(const std::string& name, std::shared_ptr<const Skeleton> skeleton);

}  // namespace costume::sim
