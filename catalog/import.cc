#include "catalog/import.h"

#include <toml++/toml.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <utility>

#include "assets/deepmimic_import.h"
#include "assets/import_units.h"
#include "assets/makehuman_import.h"
#include "assets/scene_file.h"
#include "catalog/bundle.h"
#include "catalog/catalog_loader.h"
#include "catalog/fabric_presets.h"
#include "sim_core/common/input_error.h"

namespace costume::catalog {

namespace {

namespace fs = std::filesystem;

/// An entry being prepared: where it comes from and what will be stored.
struct Candidate {
  /// The file named in messages (the main one, as the user gave it).
  std::string shown;
  /// The main file, resolved inside the root.
  fs::path path;
  NewEntry entry;
  /// A DeepMimic clip's character file, as messages name it; else empty.
  std::string character_shown;
};

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

std::string Extension(const fs::path& path) {
  const std::string extension = assets::LowerExtension(path.string());
  return extension.empty() ? extension : extension.substr(1);
}

std::vector<std::uint8_t> ReadBytes(const fs::path& path, const std::string& shown) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw sim::InputError(shown + ": cannot open the file");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) throw sim::InputError(shown + ": cannot read the file");
  if (bytes.empty()) throw sim::InputError(shown + ": the file is empty");
  return bytes;
}

std::string SizeText(std::size_t bytes) {
  std::ostringstream out;
  if (bytes >= 1 << 20) {
    out << std::fixed << std::setprecision(1) << static_cast<double>(bytes) / (1 << 20) << " MB";
  } else {
    out << (bytes + 1023) / 1024 << " KB";
  }
  return out.str();
}

/// A garment scene file and, when it names one, its mesh file (flattened into a bundle: the
/// mesh path in the stored scene file becomes its plain name).
AssetData GarmentTomlData(const fs::path& root, const fs::path& path, const std::string& shown) {
  const std::vector<std::uint8_t> bytes = ReadBytes(path, shown);
  toml::table table;
  try {
    table = toml::parse(std::string(bytes.begin(), bytes.end()), path.string());
  } catch (const toml::parse_error& error) {
    std::ostringstream message;
    message << shown << ":" << error.source().begin.line << ":" << error.source().begin.column
            << ": " << error.description();
    throw sim::InputError(message.str());
  }
  toml::node* file = table.at_path("garment[0].mesh.file").node();
  if (!file || !file->is_string()) return {"garment-toml", bytes};
  const std::string mesh_name = file->as_string()->get();
  const fs::path mesh = ResolveInsideRoot(root, (path.parent_path() / mesh_name).string());
  const std::string plain = mesh.filename().string();
  *file->as_string() = plain;
  std::ostringstream text;
  text << table;
  const std::string rewritten = text.str();
  return {"garment-toml",
          PackBundle({{path.filename().string(),
                       std::vector<std::uint8_t>(rewritten.begin(), rewritten.end())},
                      {plain, ReadBytes(mesh, shown + " (mesh " + mesh_name + ")")}})};
}

/// `file` resolved inside the root, for the part `part` of the entry of `shown`; a refusal
/// names both, and `hint`: where the file's name comes from.
fs::path ResolvePart(const fs::path& root, const std::string& file, const std::string& shown,
                     const std::string& part, const std::string& hint) {
  try {
    return ResolveInsideRoot(root, file);
  } catch (const sim::InputError& error) {
    throw sim::InputError(shown + ": " + part + ": " + error.what() + " (" + hint + ")");
  }
}

/// A MakeHuman garment (.mhclo), the garment OBJ its obj_file line names beside it, and the
/// MakeHuman body it is fitted to (base.obj, skeleton, skin weights), bundled
/// (catalog_loader.h). The body is `request.makehuman_body`, else <garment
/// folder>/../../body/base.obj (the layout of ../shared/data/makehuman); its skeleton and
/// weights are the request's, else default.mhskel and default_weights.mhw beside the body.
AssetData MakeHumanGarmentData(const fs::path& root, const ImportRequest& request,
                               const fs::path& path, const std::string& shown) {
  const std::vector<std::uint8_t> mhclo = ReadBytes(path, shown);
  std::string obj_name;
  try {
    obj_name = assets::MakeHumanGarmentObjFile(path.string());
  } catch (const sim::InputError&) {
    throw sim::InputError(shown + ": missing 'obj_file' line (the garment OBJ it is made of)");
  }
  if (fs::path(obj_name).filename() != obj_name || obj_name == "." || obj_name == "..") {
    throw sim::InputError(shown + ": obj_file '" + obj_name +
                          "' must name a file beside it (a plain file name)");
  }
  const fs::path obj = ResolvePart(root, (path.parent_path() / obj_name).string(), shown,
                                   "its garment OBJ", "named by its obj_file line");
  const fs::path body =
      ResolvePart(root,
                  request.makehuman_body.empty()
                      ? (path.parent_path() / ".." / ".." / "body" / "base.obj").string()
                      : request.makehuman_body,
                  shown, "the MakeHuman body it is fitted to", "give it with --makehuman-body");
  auto beside_body = [&](const std::string& given, const char* name) {
    return given.empty() ? (body.parent_path() / name).string() : given;
  };
  const fs::path skeleton =
      ResolvePart(root, beside_body(request.makehuman_skeleton, "default.mhskel"), shown,
                  "the MakeHuman body's skeleton", "give it with --makehuman-skeleton");
  const fs::path weights =
      ResolvePart(root, beside_body(request.makehuman_weights, "default_weights.mhw"), shown,
                  "the MakeHuman body's skin weights", "give it with --makehuman-weights");
  // Stored under their own names (the loader tells the body from the garment's OBJ by the
  // obj_file line), so messages about them name the files the user has.
  const std::string body_name = body.filename().string();
  if (body_name == obj_name || assets::LowerExtension(body_name) != ".obj" ||
      assets::LowerExtension(skeleton.string()) != ".mhskel" ||
      assets::LowerExtension(weights.string()) != ".mhw") {
    throw sim::InputError(shown + ": its MakeHuman body must be an .obj other than its garment's "
                          "('" + body_name + "'), with a .mhskel and a .mhw ('" +
                          skeleton.filename().string() + "', '" + weights.filename().string() +
                          "')");
  }
  return {"makehuman-garment",
          PackBundle({{path.filename().string(), mhclo},
                      {obj_name, ReadBytes(obj, shown + " (its garment OBJ)")},
                      {body_name, ReadBytes(body, body.string())},
                      {skeleton.filename().string(), ReadBytes(skeleton, skeleton.string())},
                      {weights.filename().string(), ReadBytes(weights, weights.string())}})};
}

/// The fabric a garment file defines: its garment's material when the file defines it, else
/// a built-in material of that name.
FabricParameters FabricOfGarmentFile(const fs::path& path) {
  const sim::SceneDescription scene =
      assets::LoadSceneFile(path.string(), assets::AvatarFiles::kRefused);
  const sim::GarmentSpec& garment = scene.garments.at(0);
  for (const sim::Material& m : scene.materials) {
    if (m.name == garment.material) return FabricFromMaterial(m);
  }
  return FabricFromMaterial(sim::NamedMaterial(garment.material));
}

/// A garment's fabric: the request's preset, else the garment file's material; a MakeHuman
/// garment gets the built-in garments' cotton, which its welded hems' slivers bear at one
/// step a frame (collision_bench simulates them in it); the presets' KES-F cottons are about
/// 30 times as stiff.
FabricParameters DefaultFabric(const Candidate& c, const ImportRequest& request) {
  if (!request.fabric_preset.empty()) return FindFabricPreset(request.fabric_preset).fabric;
  if (c.entry.data.format == "garment-toml") return FabricOfGarmentFile(c.path);
  if (c.entry.data.format == "makehuman-garment") return BuiltInGarmentFabric();
  return FabricParameters{};
}

/// The candidates of the request, before loading: files grouped into entries, bytes read.
std::vector<Candidate> Collect(const ImportRequest& request, const fs::path& root,
                               std::vector<std::string>& errors) {
  std::vector<Candidate> candidates;
  std::vector<std::pair<std::string, fs::path>> files;
  for (const std::string& file : request.files) {
    try {
      files.emplace_back(file, ResolveInsideRoot(root, file));
    } catch (const sim::InputError& error) {
      errors.push_back(error.what());
    }
  }
  auto relative = [&root](const fs::path& path) { return path.lexically_relative(root).string(); };
  auto start = [&](const std::string& shown, const fs::path& path) {
    Candidate c;
    c.shown = shown;
    c.path = path;
    c.entry.kind = request.kind;
    c.entry.name = path.stem().string();
    c.entry.category = request.category;
    c.entry.licence = request.licence;
    c.entry.provenance =
        request.provenance.empty() ? "imported from " + relative(path) : request.provenance;
    c.entry.version_label = request.label;
    return c;
  };
  // MakeHuman's triple is one avatar.
  if (request.kind == Kind::kAvatar) {
    auto find = [&](const std::string& extension) {
      return std::find_if(files.begin(), files.end(),
                          [&](const auto& f) { return Extension(f.second) == extension; });
    };
    const auto skeleton = find("mhskel");
    const auto weights = find("mhw");
    if (skeleton != files.end() || weights != files.end()) {
      const auto obj = find("obj");
      if (skeleton == files.end() || weights == files.end() || obj == files.end()) {
        errors.push_back((skeleton != files.end() ? skeleton : weights)->first +
                         ": a MakeHuman avatar needs its base .obj, .mhskel and .mhw files "
                         "given together");
        return candidates;
      }
      Candidate c = start(obj->first, obj->second);
      try {
        std::vector<BundleFile> bundle;
        for (const auto& part : {*obj, *skeleton, *weights}) {
          bundle.push_back({part.second.filename().string(), ReadBytes(part.second, part.first)});
        }
        c.entry.data = {"makehuman", PackBundle(bundle)};
        candidates.push_back(std::move(c));
      } catch (const sim::InputError& error) {
        errors.push_back(error.what());
      }
      std::erase_if(files, [&](const auto& f) {
        return f.second == obj->second || f.second == skeleton->second ||
               f.second == weights->second;
      });
    }
  }
  for (const auto& [shown, path] : files) {
    Candidate c = start(shown, path);
    try {
      const std::string format = FormatOfExtension(request.kind, Extension(path));
      if (format.empty()) {
        throw sim::InputError(shown + ": extension '." + Extension(path) + "' is not " +
                              (request.kind == Kind::kGarment ? "a " : "an ") +
                              KindName(request.kind) + " format: allowed are " +
                              (request.kind == Kind::kAvatar
                                   ? ListFormats(AvatarFileFormats(), ".") +
                                         ", MakeHuman's .obj+.mhskel+.mhw"
                               : request.kind == Kind::kAnimation
                                   ? ".bvh, " + ListFormats(AnimationFileFormats(), ".") +
                                         ", DeepMimic .txt/.json"
                                   : std::string(".toml (one [[garment]]), MakeHuman's "
                                                 ".mhclo, .cdgarment (edited garment)")));
      }
      if (format == "deepmimic") {
        // Resolved from the real motion path (a symbolic link on the way is followed), named
        // in messages as the user would write it.
        const std::string character_file =
            request.character.empty()
                ? (path.parent_path() / ".." / "characters" / "humanoid3d.txt").string()
                : request.character;
        assets::ClipImportOptions character_given;
        character_given.deepmimic_character = request.character;
        c.character_shown = assets::DeepMimicCharacterPath(shown, character_given);
        fs::path character;
        try {
          character = ResolveInsideRoot(root, character_file);
        } catch (const sim::InputError& error) {
          throw sim::InputError(shown + ": its DeepMimic character file: " + error.what() +
                                " (give it with --character)");
        }
        c.entry.data = {
            format,
            PackBundle({{"motion.txt", ReadBytes(path, shown)},
                        {"character.txt", ReadBytes(character, shown + " (character file)")}})};
      } else if (format == "garment-toml") {
        c.entry.data = GarmentTomlData(root, path, shown);
      } else if (format == "makehuman-garment") {
        c.entry.data = MakeHumanGarmentData(root, request, path, shown);
      } else {
        c.entry.data = {format, ReadBytes(path, shown)};
      }
      candidates.push_back(std::move(c));
    } catch (const sim::InputError& error) {
      errors.push_back(error.what());
    }
  }
  return candidates;
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The formats of the files ImportFiles reads itself (not through assimp), by extension.
const std::vector<std::pair<std::string, std::string>>& OwnFormats(Kind kind) {
  static const std::vector<std::pair<std::string, std::string>> avatar;
  static const std::vector<std::pair<std::string, std::string>> animation{
      {"bvh", "bvh"}, {"txt", "deepmimic"}, {"json", "deepmimic"}};
  static const std::vector<std::pair<std::string, std::string>> garment{
      {"toml", "garment-toml"}, {"mhclo", "makehuman-garment"}, {"cdgarment", "edited-garment"}};
  return kind == Kind::kAvatar ? avatar : kind == Kind::kAnimation ? animation : garment;
}

/// The formats assimp reads for `kind`, stored as the file itself.
const std::vector<std::string>& AssimpFormats(Kind kind) {
  static const std::vector<std::string> none;
  return kind == Kind::kAvatar      ? AvatarFileFormats()
         : kind == Kind::kAnimation ? AnimationFileFormats()
                                    : none;
}

}  // namespace

std::string FormatOfExtension(Kind kind, const std::string& extension) {
  const std::string e = Lower(extension);
  if (HasFormat(AssimpFormats(kind), e)) return e;
  for (const auto& [own_extension, format] : OwnFormats(kind)) {
    if (e == own_extension) return format;
  }
  return "";
}

std::vector<std::string> ImportExtensions(Kind kind) {
  std::vector<std::string> extensions;
  for (const auto& own : OwnFormats(kind)) extensions.push_back(own.first);
  for (const std::string& format : AssimpFormats(kind)) extensions.push_back(format);
  if (kind == Kind::kAvatar) {
    // A MakeHuman body is picked whole: its .obj, .mhskel and .mhw.
    for (const std::string& e : MakeHumanBodyExtensions()) {
      if (!HasFormat(extensions, e)) extensions.push_back(e);
    }
  }
  return extensions;
}

const std::vector<std::string>& MakeHumanBodyExtensions() {
  static const std::vector<std::string> extensions{"obj", "mhskel", "mhw"};
  return extensions;
}

fs::path ResolveInsideRoot(const fs::path& root, const std::string& file) {
  std::error_code error;
  const fs::path real_root = fs::canonical(root, error);
  if (error || !fs::is_directory(real_root)) {
    throw sim::InputError("import folder '" + root.string() +
                          "' is not a folder: " + (error ? error.message() : "not a directory"));
  }
  const fs::path real = fs::canonical(file, error);
  if (error) throw sim::InputError(file + ": cannot open: " + error.message());
  const fs::path inside = real.lexically_relative(real_root);
  if (inside.empty() || *inside.begin() == "..") {
    throw sim::InputError(file + ": refused: it resolves to '" + real.string() +
                          "', outside the import folder '" + real_root.string() +
                          "' (through '..', an absolute path or a symbolic link)");
  }
  if (!fs::is_regular_file(real)) throw sim::InputError(file + ": not a regular file");
  return real;
}

namespace {

/// Loads the candidate through its importer in a child process under the request's limits,
/// so a file that makes an importer allocate or loop without bound costs this process
/// nothing; then, when thumbnails are wanted, here again (the same bytes, now known to load
/// within the limits; the renderer's threads rule out drawing in the child): the request
/// for the thumbnail. Throws sim::InputError naming the file.
std::optional<ThumbnailRequest> CheckCandidate(const Candidate& c, const ImportRequest& request) {
  // The bundle the check loads from has lost the character's file name: the user's is given.
  const std::string character_what =
      std::string(kCharacterFileLabel) + (c.character_shown.empty() ? "" : " " + c.character_shown);
  const auto check = [&] {
    return CheckAssetData(c.entry.kind, c.entry.name, c.entry.data,
                          c.entry.fabric.value_or(FabricParameters{}), c.shown, character_what);
  };
  // `here` is set only where the check ran in this process (no child could be made).
  std::optional<ThumbnailRequest> here;
  CheckInChild([&] { here = check(); }, request.check_limits, c.shown, "file");
  if (!request.thumbnails) return std::nullopt;
  return here ? here : check();
}

}  // namespace

std::vector<std::int64_t> ImportFiles(Catalog& catalog, const ImportRequest& request,
                                      std::ostream& progress) {
  if (request.files.empty()) throw sim::InputError("import: no files given");
  std::error_code status;
  const fs::path root = fs::canonical(request.root.empty() ? "." : request.root, status);
  if (status || !fs::is_directory(root)) {
    throw sim::InputError("import folder --root '" + request.root + "' is not a folder" +
                          (status ? ": " + status.message() : ""));
  }
  std::vector<std::string> errors;
  std::vector<Candidate> candidates = Collect(request, root, errors);
  if (!request.name.empty()) {
    if (candidates.size() + errors.size() > 1) {
      errors.push_back("--name '" + request.name + "' names one entry, but " +
                       std::to_string(request.files.size()) + " files were given");
    } else if (!candidates.empty()) {
      candidates.front().entry.name = request.name;
    }
  }
  const int total = static_cast<int>(candidates.size());
  int index = 0;
  for (Candidate& c : candidates) {
    ++index;
    const auto start = std::chrono::steady_clock::now();
    progress << "[" << index << "/" << total << "] " << c.shown << " ("
             << SizeText(c.entry.data.bytes.size()) << ", " << c.entry.data.format
             << "): checking..." << std::flush;
    try {
      if (c.entry.kind == Kind::kAnimation && c.entry.category.empty()) c.entry.category = "basic";
      if (c.entry.kind == Kind::kGarment) {
        c.entry.fabric = DefaultFabric(c, request);
      }
      std::optional<ThumbnailRequest> thumbnail = CheckCandidate(c, request);
      progress << " loaded in " << std::fixed << std::setprecision(1) << SecondsSince(start) << " s"
               << std::flush;
      if (thumbnail) {
        progress << "; thumbnail..." << std::flush;
        thumbnail->size = request.thumbnail_size;
        try {
          c.entry.thumbnail_png = request.thumbnails(*thumbnail);
        } catch (const std::exception& error) {
          progress << " (none: " << error.what() << ")";
        }
      }
      progress << " ok\n";
    } catch (const std::exception& error) {
      progress << " refused\n";
      errors.push_back(error.what());
    }
  }
  if (!errors.empty()) {
    std::string message = std::to_string(errors.size()) + " problem" +
                          (errors.size() > 1 ? "s" : "") + "; nothing was imported:";
    for (const std::string& e : errors) message += "\n  " + e;
    throw sim::InputError(message);
  }
  std::vector<NewEntry> entries;
  for (Candidate& c : candidates) entries.push_back(std::move(c.entry));
  const std::vector<std::int64_t> ids = catalog.AddAll(entries);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    progress << "stored " << KindName(entries[i].kind) << " '" << entries[i].name << "' as id "
             << ids[i] << "\n";
  }
  return ids;
}

}  // namespace costume::catalog
