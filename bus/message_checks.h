#pragma once
/// @file
/// Array counts against vector sizes, for the messages that have variable arrays.
/// lcm-gen's encode reads `count` elements from each vector without checking its size: a
/// mismatch would read past the vector. Publisher and Publish (typed_bus.h) refuse such a
/// message instead. Never throw; never allocate.

#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"
#include "lcm_types/costume_lcm/status.hpp"

namespace costume::bus {

/// True for messages without variable-length arrays.
template <class Message>
bool CountsMatch(const Message&) {
  return true;
}

/// num_particles >= 0 and x, y, z hold num_particles values each.
bool CountsMatch(const costume_lcm::cloth_frame& message);

/// num_particles >= 0 and every particle array holds num_particles values; num_springs >= 0
/// and every spring array holds num_springs values.
bool CountsMatch(const costume_lcm::haptic_patch& message);

/// num_joints >= 0, joint_names and joint_angles hold num_joints entries, each angle row 3.
bool CountsMatch(const costume_lcm::command& message);

/// num_warnings >= 0 and warnings holds num_warnings strings.
bool CountsMatch(const costume_lcm::status& message);

}  // namespace costume::bus
