#include "sim_core/scene/body_colliders.h"

#include <algorithm>

#include "sim_core/collision/mesh_collider.h"
#include "sim_core/collision/superquadric_collider.h"

namespace costume::sim {
namespace {

/// The store of drawings a map memory of `map_memory_mb` [MB] gives
/// (SuperquadricColliderOptions::map_cache_bytes).
std::size_t MapCacheBytes(double map_memory_mb) {
  return static_cast<std::size_t>(std::max(0.0, map_memory_mb) * 1048576.0);
}

}  // namespace

std::unique_ptr<BodyCollider> MakeBodyCollider(BodyCollisionMethod method,
                                               std::shared_ptr<const Avatar> avatar,
                                               const BodyCollisionSettings& settings,
                                               double map_memory_mb) {
  if (method == BodyCollisionMethod::kMesh) {
    // The collider's default search reach (5 cm below the skin). 1.5 cm cut the method's
    // time by half but lost cloth that the kicking leg drove 2.6 cm deep in one step
    // (garment_collision_test); 3 cm held on the kick but leaves little margin.
    return std::make_unique<MeshCollider>(std::move(avatar), settings);
  }
  // The skin's own normal (stored in the distance map) rather than the superquadric's
  // gradient, which is up to 23° off at the rounded ends of limbs (docs/collision.md).
  SuperquadricColliderOptions options;
  options.contact_normal = SuperquadricColliderOptions::ContactNormal::kSkin;
  options.map_cache_bytes = MapCacheBytes(map_memory_mb);
  return std::make_unique<SuperquadricCollider>(std::move(avatar), settings, options);
}

void ApplyColliderSettings(BodyCollider& collider, const BodyCollisionSettings& settings,
                           double map_memory_mb) {
  if (auto* superquadrics = dynamic_cast<SuperquadricCollider*>(&collider)) {
    superquadrics->SetMapMemory(MapCacheBytes(map_memory_mb));
  }
  collider.SetThickness(settings.thickness);
  collider.SetFriction(settings.friction);
}

std::shared_ptr<BodyCollider> ColliderMemo::Find(BodyCollisionMethod method,
                                                 const std::shared_ptr<const Avatar>& avatar,
                                                 const BodyCollisionSettings& settings,
                                                 double map_memory_mb) {
  // The kept collider holds its avatar, so an avatar at the same address is the same one.
  // Another avatar's is let go, whatever the method: its store is no use to this one.
  if (kept_ && avatar != kept_->avatar()) kept_.reset();
  if (method == BodyCollisionMethod::kMesh) {
    // The kept one stays through a mesh collider's time: a designer comparing the methods
    // switches back to it without a refit.
    std::shared_ptr<BodyCollider> mesh =
        MakeBodyCollider(method, avatar, settings, map_memory_mb);
    ++num_builds_;
    return mesh;
  }
  if (kept_) {
    kept_->Restart();
    ApplyColliderSettings(*kept_, settings, map_memory_mb);
    return kept_;
  }
  std::shared_ptr<BodyCollider> built = MakeBodyCollider(method, avatar, settings, map_memory_mb);
  ++num_builds_;
  kept_ = std::static_pointer_cast<SuperquadricCollider>(built);
  return built;
}

}  // namespace costume::sim
