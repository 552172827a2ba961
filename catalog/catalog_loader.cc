#include "catalog/catalog_loader.h"

#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>

#include "assets/avatar_import.h"
#include "assets/clip_import.h"
#include "assets/edited_garment.h"
#include "assets/import_units.h"
#include "assets/makehuman_import.h"
#include "assets/scene_file.h"
#include "catalog/bundle.h"
#include "process/limited_child.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"

namespace costume::catalog {

namespace {

namespace fs = std::filesystem;

/// A private folder under the system's temporary folder, removed with its contents.
class TempDir {
 public:
  TempDir() {
    std::random_device random;
    const fs::path base = fs::temp_directory_path();
    for (int attempt = 0; attempt < 100; ++attempt) {
      path_ = base / ("costume-catalog-" + std::to_string(random()));
      std::error_code error;
      if (fs::create_directory(path_, error)) {
        fs::permissions(path_, fs::perms::owner_all, error);
        return;
      }
    }
    throw sim::InputError("cannot create a temporary folder under " + base.string());
  }
  ~TempDir() {
    std::error_code error;
    fs::remove_all(path_, error);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  /// Writes `bytes` to the file `name` (a plain name) in the folder; returns its path.
  /// Messages quoting that path will quote `label` instead (see Clean); empty: the name.
  std::string Write(const std::string& name, const std::vector<std::uint8_t>& bytes,
                    const std::string& label = "") {
    const fs::path file = path_ / name;
    labels_.emplace_back(file.string(), label.empty() ? name : label);
    std::ofstream out(file, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    if (!out) throw sim::InputError("cannot write the temporary file " + file.string());
    return file.string();
  }

  /// `message` with the temporary paths replaced by their labels: an importer's error then
  /// names the user's file or the catalogue entry, not a path that no longer exists.
  std::string Clean(std::string message) const {
    for (const auto& [path, label] : labels_) Replace(message, path, label);
    Replace(message, path_.string() + "/", "");
    return message;
  }

  /// Runs `load`, cleaning the message of any InputError it throws.
  template <typename Load>
  auto Guard(Load&& load) const {
    try {
      return load();
    } catch (const sim::InputError& error) {
      throw sim::InputError(Clean(error.what()));
    } catch (const std::exception& error) {  // a library's own error on malformed input
      throw sim::InputError(Clean(error.what()));
    }
  }

 private:
  static void Replace(std::string& text, const std::string& from, const std::string& to) {
    for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
      text.replace(at, from.size(), to);
    }
  }

  fs::path path_;
  std::vector<std::pair<std::string, std::string>> labels_;
};

std::string BuiltInName(const AssetData& data) {
  return std::string(data.bytes.begin(), data.bytes.end());
}

/// The bundle member whose name ends in `suffix`; throws naming `what` when there is none.
const BundleFile& Member(const std::vector<BundleFile>& files, const std::string& suffix,
                         const std::string& what) {
  for (const BundleFile& file : files) {
    if (file.name.size() >= suffix.size() &&
        file.name.compare(file.name.size() - suffix.size(), suffix.size(), suffix) == 0) {
      return file;
    }
  }
  throw sim::InputError(what + ": the bundle has no '*" + suffix + "' file");
}

std::shared_ptr<const sim::Avatar> AvatarFromData(const std::string& name, const AssetData& data,
                                                  const std::string& what) {
  if (data.format == "builtin") {
    if (BuiltInName(data) != "humanoid") {
      throw sim::InputError(what + ": unknown built-in avatar '" + BuiltInName(data) +
                            "': the built-in avatar is humanoid");
    }
    return sim::MakeHumanoid();
  }
  TempDir dir;
  if (HasFormat(AvatarFileFormats(), data.format)) {
    assets::AvatarImportOptions options;
    options.name = name;
    const std::string path = dir.Write("avatar." + data.format, data.bytes, what);
    return dir.Guard([&] { return assets::LoadAvatar(path, options); });
  }
  if (data.format == "makehuman") {
    const auto files = UnpackBundle(data.bytes, what);
    assets::MakeHumanImportOptions options;
    options.name = name;
    const BundleFile& obj = Member(files, ".obj", what);
    const BundleFile& skeleton = Member(files, ".mhskel", what);
    const BundleFile& weights = Member(files, ".mhw", what);
    const std::string obj_path = dir.Write(obj.name, obj.bytes, what + " (" + obj.name + ")");
    const std::string skeleton_path =
        dir.Write(skeleton.name, skeleton.bytes, what + " (" + skeleton.name + ")");
    const std::string weights_path =
        dir.Write(weights.name, weights.bytes, what + " (" + weights.name + ")");
    return dir.Guard([&] {
      return assets::LoadMakeHumanAvatar(obj_path, skeleton_path, weights_path, options);
    });
  }
  throw sim::InputError(what + ": format '" + data.format +
                        "' is not an avatar format: allowed are builtin, " +
                        ListFormats(AvatarFileFormats()) + ", makehuman");
}

/// `character_what` names a DeepMimic clip's character file in messages.
std::shared_ptr<const sim::Clip> ClipFromData(const std::string& name, sim::ClipCategory category,
                                              const AssetData& data, const std::string& what,
                                              const std::string& character_what) {
  if (data.format == "builtin") {
    // Made on the built-in humanoid's skeleton whatever the avatar: the angles assume its
    // world-aligned rest frames, and on an imported avatar's own skeleton (MakeHuman's bones
    // along the limbs) they twisted the body out of any walk (MakeHuman's suit walking,
    // mesh method: frames stretched up to 950 %, against at most 62 % retargeted).
    // AvatarMotion retargets the clip by H-Anim names.
    auto clip = std::make_shared<sim::Clip>(
        sim::MakeBuiltInClip(BuiltInName(data), sim::MakeHumanoidSkeleton()));
    clip->category = category;
    clip->name = name;
    return clip;
  }
  assets::ClipImportOptions options;
  options.name = name;
  options.category = category;
  TempDir dir;
  if (data.format == "bvh" || HasFormat(AnimationFileFormats(), data.format)) {
    const std::string path = dir.Write("clip." + data.format, data.bytes, what);
    return dir.Guard([&] { return std::make_shared<sim::Clip>(assets::LoadClip(path, options)); });
  }
  if (data.format == "deepmimic") {
    const auto files = UnpackBundle(data.bytes, what);
    const BundleFile& motion = Member(files, "motion.txt", what);
    const BundleFile& character = Member(files, "character.txt", what);
    options.deepmimic_character = dir.Write(character.name, character.bytes, character_what);
    const std::string path = dir.Write(motion.name, motion.bytes, what);
    return dir.Guard([&] { return std::make_shared<sim::Clip>(assets::LoadClip(path, options)); });
  }
  throw sim::InputError(what + ": format '" + data.format +
                        "' is not an animation format: allowed are builtin, bvh, " +
                        ListFormats(AnimationFileFormats()) + ", deepmimic");
}

/// A "makehuman-garment" bundle (catalog_loader.h) written out to a private folder, from
/// which its body or its garment is loaded.
class MakeHumanBundle {
 public:
  MakeHumanBundle(const AssetData& data, std::string what) : what_(std::move(what)) {
    for (const BundleFile& file : UnpackBundle(data.bytes, what_)) {
      // Messages name the .mhclo as the entry itself, the others as its parts.
      const std::string extension = assets::LowerExtension(file.name);
      const std::string label = extension == ".mhclo" ? what_ : what_ + " (" + file.name + ")";
      by_extension_[extension].push_back(dir_.Write(file.name, file.bytes, label));
    }
    mhclo_ = One(".mhclo");
    skeleton_ = One(".mhskel");
    weights_ = One(".mhw");
    dir_.Guard([&] {
      // The body is the OBJ the .mhclo does not name.
      const std::vector<std::string>& objs = Files(".obj", 2);
      const bool first_is_garment = std::filesystem::path(objs[0]).filename() ==
                                    assets::MakeHumanGarmentObjFile(mhclo_);
      body_ = objs[first_is_garment ? 1 : 0];
    });
  }

  /// The MakeHuman avatar of the body, named "MakeHuman's <its OBJ's name>".
  std::shared_ptr<const sim::Avatar> LoadBody() const {
    return dir_.Guard([&] {
      assets::MakeHumanImportOptions options;
      options.name = "MakeHuman's " + std::filesystem::path(body_).filename().string();
      return assets::LoadMakeHumanAvatar(body_, skeleton_, weights_, options);
    });
  }

  /// The garment, fitted as MakeHuman fits it and made for the body.
  sim::GarmentSpec LoadGarment() const {
    std::shared_ptr<const sim::Avatar> body = LoadBody();
    return dir_.Guard([&] {
      sim::GarmentSpec garment =
          assets::MakeHumanGarmentSpec(mhclo_, assets::ReadObj(body_), body->skeleton());
      garment.made_for = std::move(body);
      garment.mesh->source = what_;  // for the cloth's messages: the temporary folder goes
      return garment;
    });
  }

 private:
  const std::vector<std::string>& Files(const std::string& extension, std::size_t count) {
    const std::vector<std::string>& files = by_extension_[extension];
    if (files.size() != count) {
      throw sim::InputError(what_ + ": the bundle holds " + std::to_string(files.size()) + " '*" +
                            extension +
                            "' files: a MakeHuman garment has one .mhclo, .mhskel and .mhw and "
                            "two .obj (the garment's and the body's)");
    }
    return files;
  }
  std::string One(const std::string& extension) { return Files(extension, 1).front(); }

  std::string what_;
  TempDir dir_;
  std::map<std::string, std::vector<std::string>> by_extension_;  // paths written
  std::string mhclo_, body_, skeleton_, weights_;
};

sim::GarmentSpec GarmentFromData(const std::string& name, const AssetData& data,
                                 const std::string& what) {
  sim::GarmentSpec spec;
  if (data.format == "builtin") {
    spec.pattern = BuiltInName(data);
  } else if (data.format == "edited-garment") {
    const assets::EditedGarment garment = assets::ReadEditedGarment(data.bytes, what);
    spec.model = garment.model;
    spec.attach_to = garment.attached_to;
  } else if (data.format == "garment-toml") {
    TempDir dir;
    std::string path;
    if (IsBundle(data.bytes)) {
      const auto files = UnpackBundle(data.bytes, what);
      const BundleFile& toml = Member(files, ".toml", what);
      for (const BundleFile& file : files) {
        if (&file != &toml) dir.Write(file.name, file.bytes, what + " (" + file.name + ")");
      }
      path = dir.Write(toml.name, toml.bytes, what);
    } else {
      path = dir.Write("garment.toml", data.bytes, what);
    }
    const sim::SceneDescription scene =
        dir.Guard([&] { return assets::LoadSceneFile(path, assets::AvatarFiles::kRefused); });
    if (scene.garments.size() != 1) {
      throw sim::InputError(what + ": a garment file holds exactly one [[garment]] table, found " +
                            std::to_string(scene.garments.size()));
    }
    spec = scene.garments.front();
    // Messages of the cloth built later name the stored file, not the folder gone by then.
    if (spec.mesh) spec.mesh->source = dir.Clean(spec.mesh->source);
  } else if (data.format == "makehuman-garment") {
    spec = MakeHumanBundle(data, what).LoadGarment();
  } else {
    throw sim::InputError(what + ": format '" + data.format +
                          "' is not a garment format: allowed are builtin, garment-toml, "
                          "makehuman-garment, edited-garment");
  }
  spec.name = name;
  spec.material = name + "_fabric";
  return spec;
}

sim::ClipCategory CategoryOf(const EntryInfo& entry) {
  return entry.category == "choreography" ? sim::ClipCategory::kChoreography
                                          : sim::ClipCategory::kBasic;
}

EntryInfo EntryOfKind(Catalog& catalog, std::int64_t id, Kind kind) {
  EntryInfo entry = catalog.Get(id);
  if (entry.kind != kind) {
    throw sim::InputError("catalog entry " + std::to_string(id) + " ('" + entry.name + "') is " +
                          (entry.kind == Kind::kGarment ? "a " : "an ") + KindName(entry.kind) +
                          ", not " + (kind == Kind::kGarment ? "a " : "an ") + KindName(kind));
  }
  return entry;
}

std::string EntryWhat(const EntryInfo& entry, int version) {
  std::string what = std::string("catalog ") + KindName(entry.kind) + " '" + entry.name + "'";
  if (entry.kind == Kind::kGarment) {
    what += " version " + std::to_string(version ? version : entry.latest_version);
  }
  return what;
}

/// Throws InputError naming `what` unless `clip` can be retargeted onto `avatar` (the
/// built-in humanoid, which maps every joint retargeting needs): a clip whose skeleton lacks
/// them, or whose hips or thigh collapse to a point, can be put on no avatar, and is
/// refused when imported rather than when a designer first picks it.
void RequirePlayable(const sim::Clip& clip, const sim::Avatar& avatar, const std::string& what) {
  try {
    const sim::Retargeter retargeter(clip.skeleton, avatar.shared_skeleton());
  } catch (const sim::InputError& error) {
    throw sim::InputError(what + ": cannot be put on any avatar: " + error.what());
  }
}

/// The body a garment's first version names (a MakeHuman garment's), or null.
std::shared_ptr<const sim::Avatar> FirstVersionBody(const EntryInfo& entry,
                                                    const AssetData& first) {
  if (first.format != "makehuman-garment") return nullptr;
  return MakeHumanBundle(first, EntryWhat(entry, 1)).LoadBody();
}

/// A version's stored bytes and, for a saved edit, the garment's first version (whose body
/// the edit was made on): read from the database before anything parses them, so that the
/// parsing can run in a child process (which must not use this process's connection).
struct StoredVersion {
  AssetData data;
  std::optional<AssetData> first;
};

StoredVersion ReadStoredVersion(Catalog& catalog, const EntryInfo& entry, int version) {
  StoredVersion stored{catalog.Data(entry.id, version), std::nullopt};
  // Only a saved edit lacks the body it was made for; a garment's own data names it.
  if (stored.data.format == "edited-garment") stored.first = catalog.Data(entry.id, 1);
  return stored;
}

ThumbnailRequest CheckStored(const EntryInfo& entry, const StoredVersion& stored,
                             const std::string& what) {
  const std::shared_ptr<const sim::Avatar> made_for =
      stored.first ? FirstVersionBody(entry, *stored.first) : nullptr;
  return CheckAssetData(entry.kind, entry.name, stored.data,
                        entry.fabric.value_or(FabricParameters{}), what, kCharacterFileLabel,
                        made_for);
}

}  // namespace

std::shared_ptr<const sim::Avatar> LoadAvatar(Catalog& catalog, std::int64_t id) {
  const EntryInfo entry = EntryOfKind(catalog, id, Kind::kAvatar);
  return AvatarFromData(entry.name, catalog.Data(id), EntryWhat(entry, 0));
}

std::shared_ptr<const sim::Clip> LoadClip(Catalog& catalog, std::int64_t id) {
  const EntryInfo entry = EntryOfKind(catalog, id, Kind::kAnimation);
  return ClipFromData(entry.name, CategoryOf(entry), catalog.Data(id), EntryWhat(entry, 0),
                      kCharacterFileLabel);
}

std::shared_ptr<const sim::Avatar> MadeForBody(Catalog& catalog, std::int64_t id) {
  const EntryInfo entry = EntryOfKind(catalog, id, Kind::kGarment);
  return FirstVersionBody(entry, catalog.Data(id, 1));
}

sim::GarmentSpec LoadGarment(Catalog& catalog, std::int64_t id, int version) {
  const EntryInfo entry = EntryOfKind(catalog, id, Kind::kGarment);
  sim::GarmentSpec spec =
      GarmentFromData(entry.name, catalog.Data(id, version), EntryWhat(entry, version));
  // A saved edit of a MakeHuman garment is its model alone; the body is the first version's.
  if (spec.model && !spec.made_for) spec.made_for = MadeForBody(catalog, id);
  return spec;
}

sim::Material GarmentMaterial(Catalog& catalog, std::int64_t id) {
  const EntryInfo entry = EntryOfKind(catalog, id, Kind::kGarment);
  return MaterialFromFabric(entry.fabric.value_or(FabricParameters{}), entry.name + "_fabric");
}

bool AddGarmentToScene(Catalog& catalog, std::int64_t id, int version,
                       sim::SceneDescription& scene) {
  sim::GarmentSpec garment = LoadGarment(catalog, id, version);
  const sim::Material material = GarmentMaterial(catalog, id);
  std::erase_if(scene.materials, [&](const sim::Material& m) { return m.name == material.name; });
  scene.materials.push_back(material);
  bool brought_body = false;
  if (garment.made_for && scene.avatar && scene.avatar->avatar &&
      !sim::SameRestSkin(*scene.avatar->avatar, *garment.made_for)) {
    // The designer asked for the costume; it fits its own body only. As loading an avatar:
    // the clip stays, a posture for another skeleton is dropped.
    sim::Pose& posture = scene.avatar->motion.posture;
    if (posture.rotations.size() !=
        static_cast<std::size_t>(garment.made_for->skeleton().num_joints())) {
      posture.rotations.clear();
    }
    scene.avatar->avatar = garment.made_for;
    brought_body = true;
  }
  scene.garments.push_back(std::move(garment));
  return brought_body;
}

ThumbnailRequest CheckAssetData(Kind kind, const std::string& name, const AssetData& data,
                                const FabricParameters& fabric, const std::string& what,
                                const std::string& character_what,
                                std::shared_ptr<const sim::Avatar> made_for) {
  ThumbnailRequest request;
  request.kind = kind;
  request.name = name;
  switch (kind) {
    case Kind::kAvatar:
      request.avatar = AvatarFromData(name, data, what);
      break;
    case Kind::kAnimation:
      request.avatar = sim::MakeHumanoid();
      request.clip = ClipFromData(name, sim::ClipCategory::kBasic, data, what, character_what);
      RequirePlayable(*request.clip, *request.avatar, what);
      break;
    case Kind::kGarment: {
      ValidateFabric(fabric, what);
      sim::SceneDescription scene;
      scene.name = name;
      scene.source = what;
      sim::GarmentSpec garment = GarmentFromData(name, data, what);
      if (!garment.made_for) garment.made_for = std::move(made_for);
      sim::AvatarSpec avatar;
      // A garment made for one body (MakeHuman's) is shown on it.
      avatar.avatar = garment.made_for ? garment.made_for : sim::MakeHumanoid();
      request.avatar = avatar.avatar;
      scene.avatar = avatar;
      if (garment.pattern) request.pattern = *garment.pattern;
      scene.materials.push_back(MaterialFromFabric(fabric, garment.material));
      scene.garments.push_back(std::move(garment));
      // Building the model checks what the file alone cannot: pins, attachment, sizes.
      sim::ValidateScene(scene);
      std::vector<sim::GarmentRange> ranges;
      std::vector<sim::BodyAttachment> attachments;
      sim::BuildSceneModel(scene, &ranges, &attachments);
      request.garment_scene = std::move(scene);
      break;
    }
  }
  return request;
}

ThumbnailRequest CheckStoredVersion(Catalog& catalog, const EntryInfo& entry, int version,
                                    const std::string& what) {
  return CheckStored(entry, ReadStoredVersion(catalog, entry, version), what);
}

void CheckInChild(const std::function<void()>& check, const process::ChildLimits& limits,
                  const std::string& what, const std::string& subject) {
  const process::ChildResult trial = process::RunLimited(
      [&] {
        check();
        return std::string();
      },
      limits);
  switch (trial.ending) {
    case process::ChildEnding::kReturned: return;
    case process::ChildEnding::kThrew: throw sim::InputError(trial.output);
    case process::ChildEnding::kNotStarted: check(); return;  // unguarded: no child to be had
    default:
      throw sim::InputError(what + ": reading it " +
                            process::DescribeEnding(trial, limits, "--check-memory-mb",
                                                    "--check-seconds") +
                            "; the " + subject + " is likely damaged");
  }
}

std::vector<std::string> CheckEntries(Catalog& catalog, std::ostream& log,
                                      const process::ChildLimits& limits) {
  std::vector<std::string> problems = catalog.CheckIntegrity();
  for (const std::string& problem : problems) log << problem << "\n";
  for (Kind kind : {Kind::kAvatar, Kind::kAnimation, Kind::kGarment}) {
    for (const EntryInfo& entry : catalog.List(kind)) {
      for (int version = 1; version <= entry.latest_version; ++version) {
        const std::string what = EntryWhat(entry, version) + " (id " + std::to_string(entry.id) + ")";
        log << what << ": " << std::flush;  // a garment's cloth takes a moment to build
        try {
          // Stored bytes were checked when imported, but a damaged database (or another
          // program's writes) can hand an importer bytes it crashes on, ending the check.
          const StoredVersion stored = ReadStoredVersion(catalog, entry, version);
          CheckInChild([&] { CheckStored(entry, stored, what); }, limits, what, "stored data");
          log << "ok\n";
        } catch (const sim::InputError& error) {
          // The message names the entry again (the loaders quote their source), so on a line
          // of its own rather than after the name.
          log << "refused\n  " << error.what() << "\n";
          problems.push_back(error.what());
        }
      }
    }
  }
  return problems;
}

}  // namespace costume::catalog
