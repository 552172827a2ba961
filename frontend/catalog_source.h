#pragma once
/// @file
/// What the three thumbnail lists show: costumes, avatars and animations with their
/// thumbnails. From the catalogue database (catalog/catalog.h) when the build has it; from
/// the built-in assets otherwise (names only, no thumbnails), so the GUI runs either way.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "frontend/command_sender.h"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/scene_description.h"

namespace costume::frontend {

/// One entry of a list.
struct CatalogItem {
  std::int64_t id = 0;                 ///< database id (> 0), or 0 for a built-in by name
  std::string name;
  std::string category;                ///< animations: "basic" or "choreography"
  std::vector<std::uint8_t> thumbnail_png;  ///< empty: no thumbnail
};

/// A named fabric for the preset combo.
struct FabricPreset {
  std::string name;
  sim::Material material;
};

/// The lists' source.
class CatalogSource {
 public:
  virtual ~CatalogSource() = default;
  /// Every entry of `kind`, by name. May throw sim::InputError (database errors).
  virtual std::vector<CatalogItem> List(EntryKind kind) = 0;
  /// Where the entries come from, for the window title and the status bar.
  virtual std::string Describe() const = 0;
  /// Whether the entries come from a catalogue database (which `costume-catalog` can add
  /// thumbnails to), not the built-in assets.
  virtual bool IsDatabase() const { return false; }
  /// Changes `scene` as loading `item` does, for the view's mirror: kAvatar replaces the
  /// avatar (clip, posture and garments stay; pattern garments are refitted), kCostume
  /// replaces every garment with the item's (and adds its fabric), kAnimation replaces the
  /// clip. Throws sim::InputError naming the entry when it cannot (e.g. a pattern garment on a
  /// scene without avatar).
  virtual void ApplyToScene(EntryKind kind, const CatalogItem& item,
                            sim::SceneDescription& scene) = 0;
  /// Removes `item` with all its versions (catalog::Catalog::Remove). Throws sim::InputError
  /// naming it for a built-in entry or a source without a database.
  virtual void Remove(const CatalogItem& item) = 0;
};

/// The built-in assets: the humanoid; the clips of sim::BuiltInClipNames; the skirt, cape and
/// dress patterns. No thumbnails; ids 0 (LOAD_* by name).
std::unique_ptr<CatalogSource> MakeBuiltInCatalog();

/// The catalogue at `url` ("" = catalog::DefaultCatalogUrl()) when the build has the
/// catalogue library and it opens; otherwise the built-in assets, with the reason in
/// `*warning` (when not null).
std::unique_ptr<CatalogSource> OpenCatalogSource(const std::string& url, std::string* warning);

/// The import dialog's file filter for `kind`, in Qt's form ("Avatars (*.glb *.gltf …)"; a
/// garment's second filter, after ";;", adds the MakeHuman body picked with a .mhclo): the
/// extensions `costume-catalog import` takes (catalog::ImportExtensions), so the dialog
/// offers what the import reads. Empty in a build without the catalogue.
std::string ImportFilter(EntryKind kind);

/// The fabric presets for the material panel: the catalogue's fabric presets when the build
/// has them, the simulation's named materials otherwise.
std::vector<FabricPreset> FabricPresets();

}  // namespace costume::frontend
