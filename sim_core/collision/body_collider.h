#pragma once
/// @file
/// An animated obstacle the cloth collides with (the avatar's body), behind one interface
/// so the fast superquadric method and the accurate mesh method (paper §4) are chosen at
/// run time.

#include <Eigen/Geometry>
#include <span>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/collision/contact.h"

namespace costume::sim {

/// What every collider shares.
struct BodyCollisionSettings {
  /// Cloth thickness kept off the body's surface [m] >= 0.
  double thickness = 0.004;
  /// Coulomb friction coefficient between cloth and body [-] >= 0.
  double friction = 0.5;
};

/// Counters of the last FindContacts call, for benchmarks and the status bar.
struct BodyCollisionStats {
  /// Elementary tests done (particle against superquadric, or particle against region or
  /// triangle), the work the paper's adaptive regions save.
  long long num_tests = 0;
  int num_contacts = 0;
  /// Superquadric method: distance maps drawn from the skin, and maps that reused a stored
  /// drawing of the same skin (skin_map_cache.h), since the last FindContacts began.
  int num_maps_drawn = 0;
  int num_maps_reused = 0;
  /// Superquadric method: ProjectOut's searches that no map could decide (only uncertain
  /// readings inside a shell), which the segment's skin triangles then decided, since the
  /// last FindContacts began.
  int num_skin_checks = 0;
  /// ProjectOut's winding-number counts (mesh method: particles near the skin that their
  /// nearest triangle put outside; superquadric method: skin checks whose nearest skin put
  /// the particle outside, on a body of one piece), and the particles among them found
  /// inside, buried by skin that skinning moved through other skin, and moved out, since
  /// the last FindContacts began.
  int num_winding_checks = 0;
  int num_buried = 0;
};

/// Removes particle `i`'s velocity into the body along the outward `normal`, relative to
/// the velocity of the body's surface there [m/s]: what a position correction does to the
/// velocity of a particle it moves.
inline void RemoveInwardVelocity(Eigen::Index i, const Eigen::Vector3d& normal,
                                 const Eigen::Vector3d& surface_velocity, Points& velocities) {
  const double inward = (velocities.row(i).transpose() - surface_velocity).dot(normal);
  if (inward < 0.0) velocities.row(i) -= inward * normal.transpose();
}

/// Two skins (or shells) whose outward normals have a dot product below this face each
/// other across a pinch (an arm against the torso, the thighs): a push out of one is into
/// the other.
inline constexpr double kPinchFacing = -0.5;

/// In a pinch, a particle on the wall it was last pushed out of and `depth` [m] > 0 inside
/// the facing wall (normals' dot product `facing` < kPinchFacing) is as deep in both, to
/// first order, once moved back along that push by this much [m]: midway across the gap.
inline double PinchMidwayBack(double depth, double facing) { return depth / (1.0 - facing); }

class BodyCollider {
 public:
  virtual ~BodyCollider() = default;

  /// Moves the body to its pose at the end of the coming step: the joint frames from
  /// ComputeJointWorld and the skinned vertices from SkinVertices, `dt` [s] > 0 after the
  /// previous call (the body's velocity is taken from the two). The first call sets the
  /// pose with zero velocity. Never throws; allocation only on the first call.
  virtual void Update(const std::vector<Eigen::Isometry3d>& joint_world,
                      const Points& skinned_vertices, double dt) = 0;

  /// Appends a contact (contact.h) for each particle that is inside the body's shell
  /// (surface + thickness) or would end the step of length h [s] within `margin` [m] of it
  /// at `velocities` (the caller's prediction of the step's). The target normal velocity is
  /// ContactNormalVelocity's (contact.h): onto the shell from inside; from outside the
  /// particle's own, never pulling it in. Never throws.
  virtual void FindContacts(const Points& positions, const Points& velocities, double h,
                            double margin, std::vector<Contact>& contacts) = 0;

  /// Moves particles that ended inside the shell back onto it and removes their velocity
  /// into the body relative to the body (the paper's position correction). Returns the
  /// deepest penetration before the correction [m]. Never throws.
  virtual double ProjectOut(Points& positions, Points& velocities) = 0;
  /// ProjectOut for the listed `particles` (rows of `positions`) only: for a correction
  /// after one that saw every particle where it still is and left it alone. The rest are
  /// not read, beyond the bounds of all `positions`. Never throws.
  virtual double ProjectOut(Points& positions, Points& velocities,
                            std::span<const int> particles) = 0;
  /// The least correction that leaves none of the listed `particles` (rows of `positions`)
  /// inside the body, at their cost: one inside the skin itself moves onto the skin (not
  /// the shell), and its velocity into the body is removed; one within the thickness stays.
  /// For the few particles self-collision moved after ProjectOut, whose moves it must undo
  /// no more than it has to. Returns the deepest penetration of the skin before the
  /// correction [m]. Never throws.
  virtual double ProjectOutOfSkin(Points& positions, Points& velocities,
                                  std::span<const int> particles) = 0;

  virtual BodyCollisionStats stats() const = 0;

  /// Sets the Coulomb coefficient the contacts found from now on carry [-] >= 0 (the caller
  /// validates it): friction is only passed on, so nothing else is rebuilt for it. Never
  /// throws.
  virtual void SetFriction(double friction) = 0;

  /// Keeps cloth `thickness` [m] >= 0 off the surface from the next Update on (the caller
  /// validates it), without building anything the thickness does not enter. Never throws.
  virtual void SetThickness(double thickness) = 0;
};

}  // namespace costume::sim
