#include "sim_core/collision/sphere_contacts.h"

#include <algorithm>

namespace costume::sim {

void FindSphereContacts(const SphereObstacle& sphere, const Points& positions,
                        const Points& velocities, double h, double margin,
                        std::vector<Contact>& contacts) {
  const double shell = sphere.radius + sphere.thickness;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d offset = positions.row(i).transpose() - sphere.center;
    const double distance = offset.norm();
    if (distance > shell + margin + h * velocities.row(i).norm()) continue;  // cheap reject
    const Eigen::Vector3d normal =
        distance > 0.0 ? Eigen::Vector3d(offset / distance) : Eigen::Vector3d::UnitY();
    const double normal_velocity = velocities.row(i).dot(normal);
    if (distance + h * normal_velocity > shell + margin) continue;
    Contact contact;
    contact.particle = static_cast<int>(i);
    contact.normal = normal;
    contact.target_normal_velocity = (shell - distance) / h;
    contact.friction = sphere.friction;
    contact.shell_offset = normal.dot(sphere.center) + shell;
    contacts.push_back(contact);
  }
}

double ProjectOutOfSphere(const SphereObstacle& sphere, Points& positions, Points& velocities) {
  const double shell = sphere.radius + sphere.thickness;
  double deepest = 0.0;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d offset = positions.row(i).transpose() - sphere.center;
    const double distance = offset.norm();
    if (distance >= shell) continue;
    deepest = std::max(deepest, shell - distance);
    const Eigen::Vector3d normal =
        distance > 0.0 ? Eigen::Vector3d(offset / distance) : Eigen::Vector3d::UnitY();
    positions.row(i) = (sphere.center + shell * normal).transpose();
    const double inward = velocities.row(i).dot(normal);
    if (inward < 0.0) velocities.row(i) -= inward * normal.transpose();
  }
  return deepest;
}

}  // namespace costume::sim
