#pragma once
/// @file
/// The catalogue of avatars, garments (costumes) and animations (paper §7): one database the
/// whole suite shares. SQLite is the embedded default (a file created and seeded with the
/// built-in assets on first run); PostgreSQL is the shared central database of a team. Both
/// hold the same schema (docs/catalog.md), chosen by a connection URL.
///
/// Garments are versioned: saving an edited garment adds a version and never overwrites one;
/// a save is one transaction, so a writer killed mid-save leaves the previous version intact.
/// Readers see whole entries only (SQLite in WAL mode, PostgreSQL's snapshots).
///
/// Thumbnails are PNG bytes made by a ThumbnailMaker given when opening or importing, so that
/// this library does not depend on the renderer (catalog/rendered_thumbnails.h wires the
/// OSMesa renderer in).

#include <cstdint>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/scene_description.h"

namespace costume::catalog {

/// What an entry is.
enum class Kind { kAvatar, kGarment, kAnimation };

/// "avatar", "garment" or "animation" (the names the database and the command line use).
const char* KindName(Kind kind);

/// The Kind named `name` ("avatar", "garment", "animation"); throws sim::InputError listing
/// the valid names otherwise.
Kind ParseKind(const std::string& name);

/// The file formats stored as the file itself and read through assimp (AssetData::format,
/// the file's extension): an avatar may be any of them, an animation any but "vrm" and
/// "obj", which hold none.
const std::vector<std::string>& AvatarFileFormats();
const std::vector<std::string>& AnimationFileFormats();
/// Whether `formats` holds `format`.
bool HasFormat(const std::vector<std::string>& formats, const std::string& format);
/// `formats` as messages list them, each after `prefix` ("glb, gltf, ..."; ".glb, .gltf").
std::string ListFormats(const std::vector<std::string>& formats, const std::string& prefix = "");

/// A fabric's physical parameters, independent of how finely the cloth is sampled; the
/// same quantities as sim::Material (sim_core/cloth/material.h).
struct FabricParameters {
  /// Mass per area [kg/m²] > 0 (sim::Material::density).
  double mass_per_area = 0.1;
  /// Sheet stretch stiffness [N/m] > 0 (sim::Material::stretch_stiffness).
  double stretch_stiffness = 1000.0;
  /// Sheet shear stiffness [N/m] > 0 (sim::Material::shear_stiffness).
  double shear_stiffness = 1000.0;
  /// Bending rigidity [N·m] = [N·m²/m] >= 0 (sim::Material::bending_rigidity; Kawabata's B
  /// in gf·cm²/cm is 9.81e-5 N·m).
  double bend_stiffness = 1e-5;
  /// Spring damping time [s] >= 0 (sim::Material::damping: c = damping · k).
  double damping = 1e-3;
  /// Coulomb friction coefficient against obstacles [-] >= 0 (sim::Material::friction).
  double friction = 0.3;
};

/// The parameters of `material` (air drag and per-spring overrides are not kept).
FabricParameters FabricFromMaterial(const sim::Material& material);

/// A sim::Material named `name` with these parameters (air drag sim::Material's default).
sim::Material MaterialFromFabric(const FabricParameters& fabric, const std::string& name);

/// Throws sim::InputError naming `context`.field, its value and range, for a parameter out
/// of its physical range (sim::ValidateMaterial's ranges).
void ValidateFabric(const FabricParameters& fabric, const std::string& context);

/// One entry of the catalogue, without its data.
struct EntryInfo {
  /// Database id, > 0.
  std::int64_t id = 0;
  Kind kind = Kind::kAvatar;
  /// Unique within its kind.
  std::string name;
  /// Animations: "basic" or "choreography"; other kinds: free text (may be empty).
  std::string category;
  /// Where it comes from ("built-in", an author, a file name) and under which licence.
  std::string provenance, licence;
  /// Creation and last-change times [µs since the Unix epoch].
  std::int64_t created_utime = 0, modified_utime = 0;
  /// Garments: the newest version, >= 1; other kinds: 1.
  int latest_version = 1;
  /// Garments: the fabric; other kinds: none.
  std::optional<FabricParameters> fabric;
};

/// An entry's data, as stored.
struct AssetData {
  /// "builtin": `bytes` are the built-in's name ("humanoid"; "stand", "walk", ...; "skirt", "cape",
  /// "dress"). Otherwise the file format: "glb", "gltf", "fbx", "dae", "obj" (avatars, and
  /// glTF/FBX/Collada clips), "vrm" (avatars), "bvh", "deepmimic" (a bundle: motion and character
  /// file, catalog/bundle.h), "makehuman" (a bundle: base.obj, .mhskel, .mhw); garments:
  /// "garment-toml" (a scene file holding one [[garment]] table, with a mesh file in a bundle when
  /// it uses one; see catalog_loader.h), "makehuman-garment" (a bundle: the .mhclo, its garment OBJ
  /// and the MakeHuman body it is fitted to; catalog_loader.h) or "edited-garment"
  /// (assets/edited_garment.h).
  std::string format;
  std::vector<std::uint8_t> bytes;
};

/// One saved version of a garment.
struct VersionInfo {
  /// 1, 2, ... in saving order.
  int version = 1;
  /// What the designer called it ("initial", "shortened hem").
  std::string label;
  /// When it was saved [µs since the Unix epoch].
  std::int64_t created_utime = 0;
};

/// What a thumbnail is to show; the objects are already loaded.
struct ThumbnailRequest {
  Kind kind = Kind::kAvatar;
  std::string name;
  /// Avatars: the avatar (rest pose). Animations: the avatar the clip plays on (the built-in
  /// humanoid). Garments: the default avatar they are shown on.
  std::shared_ptr<const sim::Avatar> avatar;
  /// Animations: the clip (shown mid-clip).
  std::shared_ptr<const sim::Clip> clip;
  /// Garments: a scene with the default avatar and this garment (and its material).
  std::optional<sim::SceneDescription> garment_scene;
  /// Garments: the built-in pattern's name when it is one ("skirt"), else empty.
  std::string pattern;
  /// Edge length of the square image [px].
  int size = 128;
};

/// Makes a thumbnail's PNG bytes; an empty vector for "no thumbnail". May throw
/// sim::InputError, which the caller reports (the entry is then stored without one).
using ThumbnailMaker = std::function<std::vector<std::uint8_t>(const ThumbnailRequest&)>;

/// How Catalog::Open prepares a database.
struct OpenOptions {
  /// Seed the built-in assets into an empty database.
  bool seed = true;
  /// Thumbnails for the seeded entries; none: they are seeded without (see
  /// Catalog::FillMissingThumbnails).
  ThumbnailMaker thumbnails;
  /// Edge length of seeded thumbnails [px].
  int thumbnail_size = 128;
};

/// A new entry, as the import command makes it.
struct NewEntry {
  Kind kind = Kind::kAvatar;
  std::string name;
  std::string category;
  std::string provenance;
  std::string licence;
  /// Garments: required.
  std::optional<FabricParameters> fabric;
  AssetData data;
  /// PNG bytes, may be empty.
  std::vector<std::uint8_t> thumbnail_png;
  /// Garments: the first version's label.
  std::string version_label = "initial";
};

class SqlConnection;

/// The catalogue. Each method is one transaction; an object is used by one thread at a time
/// (open one per thread or process). Every method throws sim::InputError naming the URL for
/// a database error, and naming the id or name for an entry that does not exist.
class Catalog {
 public:
  /// Opens the catalogue at `url`: "sqlite:<path>", a bare path (SQLite), or
  /// "postgresql://..." / "postgres://..." (libpq's URI syntax). Creates the file and the
  /// schema, applies pending schema migrations and, when the database has no entries and
  /// options.seed is set, seeds the built-in assets. Throws sim::InputError naming the URL.
  static std::unique_ptr<Catalog> Open(const std::string& url, const OpenOptions& options = {});
  virtual ~Catalog();
  Catalog(const Catalog&) = delete;
  Catalog& operator=(const Catalog&) = delete;

  /// The URL it was opened with, any password starred out (as messages quote it).
  const std::string& url() const { return url_; }
  /// The schema version in use (the last migration applied).
  int schema_version();

  /// Every entry of `kind`, by name.
  std::vector<EntryInfo> List(Kind kind);
  /// The entry of `kind` called `name`, if any.
  std::optional<EntryInfo> Find(Kind kind, const std::string& name);
  /// The entry `id`; throws sim::InputError when there is none.
  EntryInfo Get(std::int64_t id);
  /// The entry's thumbnail (PNG bytes; of the latest version for garments), empty when none.
  std::vector<std::uint8_t> Thumbnail(std::int64_t id);
  /// The data of version `version` (0: the latest) of entry `id`; non-garments have only
  /// version 1. Throws sim::InputError for an unknown id or version.
  AssetData Data(std::int64_t id, int version = 0);
  /// The versions of a garment, oldest first. Throws for an id that is not a garment.
  std::vector<VersionInfo> Versions(std::int64_t garment_id);
  /// Adds the next version of a garment in one transaction (never overwrites one) and makes
  /// it the latest; returns its number. Throws for an id that is not a garment or empty data.
  int SaveGarmentVersion(std::int64_t garment_id, const AssetData& data, const std::string& label,
                         const std::vector<std::uint8_t>& thumbnail_png);
  /// Adds an entry (garments: with version 1) in one transaction; returns its id. Throws
  /// sim::InputError when the kind already has an entry of that name, the name is empty, an
  /// animation's category is not "basic" or "choreography", or a garment has no fabric.
  std::int64_t Add(const NewEntry& entry);
  /// Adds several entries in one transaction: all of them or, when one is refused, none.
  std::vector<std::int64_t> AddAll(const std::vector<NewEntry>& entries);
  /// Removes entry `id` with all its versions, thumbnails and fabric in one transaction and
  /// returns what it was. Throws sim::InputError for an unknown id and for a built-in entry
  /// (scene files and the defaults name them). A simulation that has the entry loaded keeps
  /// it; lists show the removal when next filled.
  EntryInfo Remove(std::int64_t id);
  /// Sets a garment's fabric parameters (validated first).
  void SetFabric(std::int64_t garment_id, const FabricParameters& fabric);
  /// Replaces the thumbnail of entry `id` (garments: of its latest version).
  void SetThumbnail(std::int64_t id, const std::vector<std::uint8_t>& png);
  /// Makes the thumbnails that are missing with `maker` (the database was seeded without a
  /// renderer, or a garment version was saved by the simulation server, which renders none);
  /// returns how many were made. Writes a line per entry to `log` ("garment 'skirt' (id 8):
  /// thumbnail... ok", or the reason when its data cannot be loaded or rendered, which skips
  /// it).
  int FillMissingThumbnails(const ThumbnailMaker& maker, int size = 128,
                            std::ostream& log = std::cerr);
  /// Checks the database: SQLite's integrity_check and foreign_key_check, and for every
  /// entry that its versions are exactly 1..latest_version, non-garments have one version,
  /// garments have a fabric, its name is one short line (as Add requires). Returns the
  /// problems found (empty: consistent). CheckEntries (catalog_loader.h) also loads them.
  std::vector<std::string> CheckIntegrity();

 private:
  Catalog(std::string url, std::unique_ptr<SqlConnection> connection);
  void Migrate();
  void Seed(const OpenOptions& options);
  std::string url_;
  std::unique_ptr<SqlConnection> db_;
};

/// The catalogue URL to use: $COSTUME_CATALOG if set and non-empty, else
/// "sqlite:$XDG_DATA_HOME/costume-designer/catalog.sqlite", $XDG_DATA_HOME defaulting to
/// ~/.local/share (the directory is created when the catalogue is opened).
std::string DefaultCatalogUrl();

/// `url` with any password replaced by "***" ("postgresql://ada:***@host/db"), for messages.
std::string RedactedUrl(const std::string& url);

/// The licence of the built-in assets: this project's own (the repository has no separate
/// licence file yet; the built-ins are generated by its code).
inline constexpr const char* kBuiltInLicence = "Costume Designer project licence";
/// The provenance of the built-in assets.
inline constexpr const char* kBuiltInProvenance = "built-in";

}  // namespace costume::catalog
