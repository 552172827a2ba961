#include "frontend/catalog_source.h"

#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#ifdef COSTUME_HAVE_CATALOG
#include "catalog/catalog.h"
#include "catalog/catalog_loader.h"
#include "catalog/fabric_presets.h"
#include "catalog/import.h"
#include "catalog/rendered_thumbnails.h"
#endif

namespace costume::frontend {
namespace {

/// The scene's avatar; throws when there is none (the item needs one).
sim::AvatarSpec& RequireAvatar(sim::SceneDescription& scene, const CatalogItem& item) {
  if (!scene.avatar) {
    throw sim::InputError("'" + item.name + "' needs a scene with an avatar; scene '" +
                          scene.name + "' has none");
  }
  return *scene.avatar;
}

class BuiltInCatalog final : public CatalogSource {
 public:
  std::vector<CatalogItem> List(EntryKind kind) override {
    std::vector<std::string> names;
    switch (kind) {
      case EntryKind::kAvatar: names = {"humanoid"}; break;
      case EntryKind::kCostume: names = {"cape", "dress", "skirt"}; break;
      case EntryKind::kAnimation: names = sim::BuiltInClipNames(); break;
    }
    std::vector<CatalogItem> items;
    for (const std::string& name : names) {
      items.push_back({0, name, kind == EntryKind::kAnimation ? "basic" : "", {}});
    }
    return items;
  }
  std::string Describe() const override { return "built-in assets (no catalogue database)"; }

  void ApplyToScene(EntryKind kind, const CatalogItem& item, sim::SceneDescription& scene) override {
    switch (kind) {
      case EntryKind::kAvatar:
        RequireAvatar(scene, item).avatar = sim::MakeHumanoid();
        return;
      case EntryKind::kAnimation: {
        // On the skeleton its angles are written for, retargeted onto the avatar when
        // played (as catalog::LoadClip).
        RequireAvatar(scene, item).clip = std::make_shared<const sim::Clip>(
            sim::MakeBuiltInClip(item.name, sim::MakeHumanoidSkeleton()));
        return;
      }
      case EntryKind::kCostume: {
        RequireAvatar(scene, item);
        sim::GarmentSpec garment;
        garment.name = item.name;
        garment.pattern = item.name;
        if (!scene.garments.empty()) garment.material = scene.garments.front().material;
        scene.garments = {garment};
        return;
      }
    }
  }

  void Remove(const CatalogItem& item) override {
    throw sim::InputError("'" + item.name + "' is built in, and there is no catalogue database "
                          "to remove entries from");
  }
};

#ifdef COSTUME_HAVE_CATALOG
catalog::Kind CatalogKind(EntryKind kind) {
  switch (kind) {
    case EntryKind::kAvatar: return catalog::Kind::kAvatar;
    case EntryKind::kCostume: return catalog::Kind::kGarment;
    case EntryKind::kAnimation: return catalog::Kind::kAnimation;
  }
  return catalog::Kind::kAvatar;
}

class DatabaseCatalog final : public CatalogSource {
 public:
  explicit DatabaseCatalog(std::unique_ptr<catalog::Catalog> db) : db_(std::move(db)) {}
  std::vector<CatalogItem> List(EntryKind kind) override {
    std::vector<CatalogItem> items;
    for (const catalog::EntryInfo& entry : db_->List(CatalogKind(kind))) {
      items.push_back({entry.id, entry.name, entry.category, db_->Thumbnail(entry.id)});
    }
    return items;
  }
  std::string Describe() const override { return db_->url(); }
  bool IsDatabase() const override { return true; }
  void Remove(const CatalogItem& item) override { db_->Remove(item.id); }

  void ApplyToScene(EntryKind kind, const CatalogItem& item, sim::SceneDescription& scene) override {
    switch (kind) {
      case EntryKind::kAvatar: {
        // As the server (sim_core/app/catalog_link.cc): a scene without avatar gets one; a
        // posture for another skeleton is dropped (rest pose, same placement).
        auto avatar = catalog::LoadAvatar(*db_, item.id);
        if (!scene.avatar) scene.avatar.emplace();
        sim::Pose& posture = scene.avatar->motion.posture;
        if (posture.rotations.size() != static_cast<std::size_t>(avatar->skeleton().num_joints())) {
          posture.rotations.clear();
        }
        scene.avatar->avatar = std::move(avatar);
        return;
      }
      case EntryKind::kAnimation: {
        sim::AvatarSpec& avatar = RequireAvatar(scene, item);
        avatar.clip = catalog::LoadClip(*db_, item.id);
        return;
      }
      case EntryKind::kCostume:
        scene.garments.clear();
        catalog::AddGarmentToScene(*db_, item.id, 0, scene);
        return;
    }
  }

 private:
  std::unique_ptr<catalog::Catalog> db_;
};
#endif

}  // namespace

std::unique_ptr<CatalogSource> MakeBuiltInCatalog() { return std::make_unique<BuiltInCatalog>(); }

std::unique_ptr<CatalogSource> OpenCatalogSource(const std::string& url, std::string* warning) {
#ifdef COSTUME_HAVE_CATALOG
  try {
    return std::make_unique<DatabaseCatalog>(
        catalog::Catalog::Open(url.empty() ? catalog::DefaultCatalogUrl() : url,
                               catalog::WithRenderedThumbnails()));
  } catch (const sim::InputError& error) {
    if (warning) *warning = std::string("catalogue not opened: ") + error.what();
  }
#else
  if (warning && !url.empty()) *warning = "this build has no catalogue library; showing built-ins";
#endif
  return MakeBuiltInCatalog();
}

#ifdef COSTUME_HAVE_CATALOG
namespace {

/// "*.a *.b" for a file dialog.
std::string Patterns(const std::vector<std::string>& extensions) {
  std::string patterns;
  for (const std::string& e : extensions) patterns += (patterns.empty() ? "*." : " *.") + e;
  return patterns;
}

}  // namespace
#endif

std::string ImportFilter(EntryKind kind) {
#ifdef COSTUME_HAVE_CATALOG
  switch (kind) {
    case EntryKind::kAvatar:
      return "Avatars (" + Patterns(catalog::ImportExtensions(catalog::Kind::kAvatar)) + ")";
    case EntryKind::kAnimation:
      return "Animations (" + Patterns(catalog::ImportExtensions(catalog::Kind::kAnimation)) +
             ")";
    case EntryKind::kCostume: {
      std::vector<std::string> with_body{"mhclo"};
      for (const std::string& e : catalog::MakeHumanBodyExtensions()) with_body.push_back(e);
      return "Costumes (" + Patterns(catalog::ImportExtensions(catalog::Kind::kGarment)) +
             ");;MakeHuman garments with their body (" + Patterns(with_body) + ")";
    }
  }
#endif
  (void)kind;
  return "";
}

std::vector<FabricPreset> FabricPresets() {
  // The engine's table (sim_core/cloth/fabric_presets.h), as scene files and the catalogue
  // read it, then the benchmark materials.
  std::vector<FabricPreset> presets;
  for (const std::string& name : sim::NamedMaterialNames()) {
    presets.push_back({name, sim::NamedMaterial(name)});
  }
  return presets;
}

}  // namespace costume::frontend
