#pragma once
/// @file
/// The colliders a scene's avatar gets (superquadric_collider.h, mesh_collider.h), and the
/// one kept for the next simulation built for the same avatar.

#include <memory>

#include "sim_core/avatar/avatar.h"
#include "sim_core/collision/body_collider.h"
#include "sim_core/scene/scene_description.h"

namespace costume::sim {

class SuperquadricCollider;

/// The collider `method` builds around `avatar` (superquadric_collider.h, mesh_collider.h);
/// the superquadric one keeps up to `map_memory_mb` [MB] of its maps' drawings for reuse
/// (SuperquadricColliderOptions::map_cache_bytes).
std::unique_ptr<BodyCollider> MakeBodyCollider(BodyCollisionMethod method,
                                               std::shared_ptr<const Avatar> avatar,
                                               const BodyCollisionSettings& settings,
                                               double map_memory_mb);

/// Gives `collider` in place what MakeBodyCollider would build one with: a superquadric
/// collider's store of `map_memory_mb` [MB] for its drawings (SuperquadricCollider::
/// SetMapMemory, which forgets them when the budget changes; other colliders store none),
/// then `settings` (BodyCollider::SetThickness, SetFriction). Nothing is fitted again.
/// Throws std::bad_alloc, before anything else changes, when the store cannot be reserved.
void ApplyColliderSettings(BodyCollider& collider, const BodyCollisionSettings& settings,
                           double map_memory_mb);

/// The superquadric collider last built, kept for the next simulation built for the same
/// avatar: a server's STOP, a new fabric or another costume on the same body rebuilds the
/// simulation from its scene. Building the collider takes 0.4 s on the built-in humanoid
/// and 0.65 s on MakeHuman's body, and a new one has no drawings stored, so a looping
/// clip's first pass, slower than real time on MakeHuman, came again after each rebuild
/// (docs/collision.md, "Kept across rebuilds"). A mesh collider is not kept: it is
/// built in about 0.05 s and draws nothing. The superquadric one stays kept while a mesh
/// collider is used for the same avatar, so switching back to it costs no refit.
///
/// The simulations built with one memo share its collider: only the last one built may step
/// (a server replaces its simulation with each one it builds). A build that throws leaves
/// the kept collider as it was, so the simulation before it may go on.
class ColliderMemo {
 public:
  /// For the superquadric method, the kept collider, restarted (SuperquadricCollider::
  /// Restart) and given `settings` and `map_memory_mb` (ApplyColliderSettings), when it was
  /// built for `avatar`; else a new one, kept (the one kept before, another avatar's, is
  /// let go first).
  /// For the mesh method, a new one (the kept one is let go when it is another avatar's).
  /// Throws what MakeBodyCollider throws.
  std::shared_ptr<BodyCollider> Find(BodyCollisionMethod method,
                                     const std::shared_ptr<const Avatar>& avatar,
                                     const BodyCollisionSettings& settings,
                                     double map_memory_mb);
  /// Colliders built since construction [-].
  int num_builds() const { return num_builds_; }

 private:
  /// Its avatar is the key (SuperquadricCollider::avatar).
  std::shared_ptr<SuperquadricCollider> kept_;
  int num_builds_ = 0;
};

}  // namespace costume::sim
