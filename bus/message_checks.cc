#include "bus/message_checks.h"

namespace costume::bus {

namespace {
template <class... Vectors>
bool AllHaveSize(int count, const Vectors&... vectors) {
  return count >= 0 && ((vectors.size() == static_cast<std::size_t>(count)) && ...);
}
}  // namespace

bool CountsMatch(const costume_lcm::cloth_frame& m) {
  return AllHaveSize(m.num_particles, m.x, m.y, m.z);
}

bool CountsMatch(const costume_lcm::haptic_patch& m) {
  return AllHaveSize(m.num_particles, m.particle_index, m.x, m.y, m.z, m.vx, m.vy, m.vz, m.mass,
                     m.selected, m.weight) &&
         AllHaveSize(m.num_springs, m.spring_a, m.spring_b, m.stiffness, m.damping,
                     m.rest_length);
}

bool CountsMatch(const costume_lcm::command& m) {
  if (!AllHaveSize(m.num_joints, m.joint_names, m.joint_angles)) return false;
  for (const auto& row : m.joint_angles) {
    if (row.size() != 3) return false;
  }
  return true;
}

bool CountsMatch(const costume_lcm::status& m) { return AllHaveSize(m.num_warnings, m.warnings); }

}  // namespace costume::bus
