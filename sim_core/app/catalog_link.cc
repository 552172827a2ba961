#include "sim_core/app/catalog_link.h"

#include <utility>

#include "assets/edited_garment.h"
#include "catalog/catalog_loader.h"
#include "sim_core/common/input_error.h"

namespace costume::sim_app {

namespace {

catalog::Kind KindOf(LoadKind kind) {
  switch (kind) {
    case LoadKind::kAvatar: return catalog::Kind::kAvatar;
    case LoadKind::kAnimation: return catalog::Kind::kAnimation;
    case LoadKind::kCostume: break;
  }
  return catalog::Kind::kGarment;
}

/// "a garment", "an avatar", "an animation".
std::string WithArticle(catalog::Kind kind) {
  return std::string(kind == catalog::Kind::kGarment ? "a " : "an ") + catalog::KindName(kind);
}

std::string Describe(const catalog::EntryInfo& entry) {
  return std::string(catalog::KindName(entry.kind)) + " '" + entry.name + "' (id " +
         std::to_string(entry.id) + ")";
}

class DatabaseSceneCatalog final : public SceneCatalog {
 public:
  explicit DatabaseSceneCatalog(std::unique_ptr<catalog::Catalog> catalog)
      : catalog_(std::move(catalog)) {}

  std::string Load(LoadKind kind, std::int64_t id, const std::string& name,
                   sim::SceneDescription& scene) override {
    const catalog::EntryInfo entry = Resolve(KindOf(kind), id, name);
    sim::SceneDescription changed = scene;
    switch (kind) {
      case LoadKind::kAvatar: LoadAvatar(entry, changed); break;
      case LoadKind::kAnimation: LoadAnimation(entry, changed); break;
      case LoadKind::kCostume:
        changed.garments.clear();
        catalog::AddGarmentToScene(*catalog_, entry.id, 0, changed);
        break;
    }
    scene = std::move(changed);
    std::string what = Describe(entry);
    if (kind == LoadKind::kCostume) what += " version " + std::to_string(entry.latest_version);
    return what;
  }

  SavedVersion SaveVersion(const sim::Simulation& simulation, const std::string& garment,
                           const std::string& label) override {
    const std::optional<catalog::EntryInfo> entry =
        catalog_->Find(catalog::Kind::kGarment, garment);
    if (!entry) {
      throw sim::InputError("the catalogue " + catalog_->url() + " has no garment called '" +
                            garment + "' to add a version to");
    }
    const assets::EditedGarment edited = assets::EditedGarmentFromSimulation(simulation, garment);
    const catalog::AssetData data{"edited-garment", assets::WriteEditedGarment(edited)};
    // No thumbnail here: rendering one would stall the 60 Hz loop (draping a garment takes
    // seconds); `costume-catalog thumbnails` (FillMissingThumbnails) makes it later, run by
    // the GUI when it sees this save.
    const int version = catalog_->SaveGarmentVersion(entry->id, data, label, {});
    return {Describe(*entry), version};
  }

 private:
  /// The entry `id` (> 0) or the one of `kind` called `name`; throws naming the one asked for.
  catalog::EntryInfo Resolve(catalog::Kind kind, std::int64_t id, const std::string& name) {
    if (id > 0) {
      catalog::EntryInfo entry = catalog_->Get(id);  // throws for an unknown id
      if (entry.kind != kind) {
        throw sim::InputError("catalog entry " + std::to_string(id) + " ('" + entry.name +
                              "') is " + WithArticle(entry.kind) + ", not " +
                              WithArticle(kind));
      }
      return entry;
    }
    std::optional<catalog::EntryInfo> entry = catalog_->Find(kind, name);
    if (!entry) {
      throw sim::InputError("the catalogue " + catalog_->url() + " has no " +
                            catalog::KindName(kind) + " called '" + name + "'");
    }
    return *entry;
  }

  // The clip stays (the simulation retargets it onto the new skeleton); garments with a
  // built-in pattern are fitted to the new body when the scene is built. A posture given
  // for the old skeleton does not fit another one: the new avatar starts from its rest pose
  // (the placement stays).
  void LoadAvatar(const catalog::EntryInfo& entry, sim::SceneDescription& scene) {
    auto avatar = catalog::LoadAvatar(*catalog_, entry.id);
    if (!scene.avatar) scene.avatar.emplace();
    sim::Pose& posture = scene.avatar->motion.posture;
    if (posture.rotations.size() != static_cast<std::size_t>(avatar->skeleton().num_joints())) {
      posture.rotations.clear();
    }
    scene.avatar->avatar = std::move(avatar);
  }

  void LoadAnimation(const catalog::EntryInfo& entry, sim::SceneDescription& scene) {
    if (!scene.avatar || !scene.avatar->avatar) {
      throw sim::InputError(Describe(entry) + ": the scene has no avatar to play it on; load "
                            "an avatar first");
    }
    scene.avatar->clip = catalog::LoadClip(*catalog_, entry.id);
  }

  std::unique_ptr<catalog::Catalog> catalog_;
};

}  // namespace

std::unique_ptr<SceneCatalog> MakeSceneCatalog(std::unique_ptr<catalog::Catalog> catalog) {
  return std::make_unique<DatabaseSceneCatalog>(std::move(catalog));
}

std::unique_ptr<SceneCatalog> OpenSceneCatalog(const std::string& url) {
  return MakeSceneCatalog(catalog::Catalog::Open(url));
}

}  // namespace costume::sim_app
