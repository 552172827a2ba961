#pragma once
/// @file
/// Contacts of cloth particles with a fixed analytic sphere (the drape benchmark's obstacle).

#include <Eigen/Core>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/collision/contact.h"

namespace costume::sim {

struct SphereObstacle {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  /// Radius [m] > 0.
  double radius = 0.25;
  /// Cloth thickness kept off the surface [m] >= 0.
  double thickness = 0.005;
  /// Coulomb friction coefficient [-].
  double friction = 0.3;
};

/// Appends a contact for each particle that is inside the sphere's shell (radius +
/// thickness), or would end the step of length h [s] within `margin` [m] of it moving at
/// its current velocity. Never allocates beyond `contacts`' capacity growth.
void FindSphereContacts(const SphereObstacle& sphere, const Points& positions,
                        const Points& velocities, double h, double margin,
                        std::vector<Contact>& contacts);

/// Moves any particle that ended inside the shell back onto it and removes its inward
/// normal velocity (the paper's position correction). Returns the deepest penetration
/// found before the correction [m] (0 when none).
double ProjectOutOfSphere(const SphereObstacle& sphere, Points& positions, Points& velocities);

}  // namespace costume::sim
