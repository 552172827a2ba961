#pragma once
/// @file
/// The built-in humanoid, made once per test program (about 6,400 vertices, tens of ms).

#include <memory>

#include "sim_core/avatar/procedural_humanoid.h"

namespace costume::test {

inline const std::shared_ptr<const sim::Avatar>& Humanoid() {
  static const std::shared_ptr<const sim::Avatar> avatar = sim::MakeHumanoid();
  return avatar;
}

}  // namespace costume::test
