/// costume-catalog: the catalogue of avatars, garments and animations from the command line
/// (docs/catalog.md). Subcommands: import, list, versions, export. Not called `import`,
/// which ImageMagick owns on users' machines.

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "catalog/bundle.h"
#include "catalog/catalog.h"
#include "catalog/catalog_loader.h"
#include "catalog/import.h"
#include "catalog/rendered_thumbnails.h"
#include "sim_core/common/input_error.h"

namespace {

using costume::catalog::Catalog;
using costume::catalog::EntryInfo;
using costume::catalog::Kind;

std::string FormatTime(std::int64_t utime) {
  const std::time_t seconds = static_cast<std::time_t>(utime / 1000000);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S", std::gmtime(&seconds));
  return text;
}

bool IsDigits(const std::string& text) {
  return !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
}

/// An entry named by id or by name (for `versions`: a garment's name). Digits are an id
/// when there is an entry of that id, else a name ("1920", a costume named by its period).
EntryInfo Resolve(Catalog& catalog, const std::string& what, Kind kind_for_names) {
  if (IsDigits(what) && what.size() < 19) {  // longer ones overflow an id
    try {
      return catalog.Get(std::stoll(what));
    } catch (const costume::sim::InputError&) {
      if (!catalog.Find(kind_for_names, what)) throw;
    }
  }
  const auto entry = catalog.Find(kind_for_names, what);
  if (!entry) {
    throw costume::sim::InputError("no " + std::string(KindName(kind_for_names)) + " named '" +
                                   what + "' in " + catalog.url());
  }
  return *entry;
}

/// `remove`: the entry named by id, or by name and kind; with `yes` it is removed, without
/// only described (a removal cannot be undone, and a team may share the catalogue).
void Remove(Catalog& catalog, const std::string& what, const std::string& kind, bool yes) {
  if (!IsDigits(what) && kind.empty()) {
    throw costume::sim::InputError("remove '" + what + "': a name needs --kind (avatar, "
                                   "animation or garment); or give the id ('list' shows it)");
  }
  const EntryInfo entry =
      Resolve(catalog, what, kind.empty() ? Kind::kGarment : costume::catalog::ParseKind(kind));
  if (!kind.empty() && KindName(entry.kind) != kind) {
    throw costume::sim::InputError("remove " + what + ": entry " + std::to_string(entry.id) +
                                   " ('" + entry.name + "') is " + KindName(entry.kind) +
                                   ", not " + kind + "; nothing removed");
  }
  const std::string described = std::string(KindName(entry.kind)) + " '" + entry.name + "' (id " +
                                std::to_string(entry.id) + ", " +
                                std::to_string(entry.latest_version) + " version(s))";
  if (!yes) {
    std::printf("would remove %s; nothing removed: run again with --yes\n", described.c_str());
    return;
  }
  catalog.Remove(entry.id);
  std::printf("removed %s\n", described.c_str());
}

void PrintList(Catalog& catalog, const std::vector<Kind>& kinds) {
  std::printf("%-6s %-10s %-24s %-14s %-8s %-19s %s\n", "id", "kind", "name", "category", "version",
              "modified (UTC)", "provenance / licence");
  for (Kind kind : kinds) {
    for (const EntryInfo& e : catalog.List(kind)) {
      std::printf("%-6lld %-10s %-24s %-14s %-8d %-19s %s / %s\n", static_cast<long long>(e.id),
                  KindName(e.kind), e.name.c_str(), e.category.c_str(), e.latest_version,
                  FormatTime(e.modified_utime).c_str(), e.provenance.c_str(), e.licence.c_str());
    }
  }
}

/// Writes `bytes` to `path`, or throws InputError naming it: when it exists and `force` is
/// off (an export replaced a user's file without a word), or when it cannot be written.
void WriteOut(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes,
              bool force) {
  if (!force && std::filesystem::exists(path)) {
    throw costume::sim::InputError(path.string() + ": already exists (--force replaces it)");
  }
  std::ofstream file(path, std::ios::binary);
  const auto refuse = [&] {
    throw costume::sim::InputError(path.string() + ": cannot write: " + std::strerror(errno));
  };
  if (!file) refuse();
  file.write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  file.close();
  if (!file) refuse();
}

/// How a scene file names the built-in whose stored bytes are `name` (docs/scene_format.md).
std::string SceneFileReference(Kind kind, const std::vector<std::uint8_t>& name) {
  if (kind == Kind::kAvatar) return "model = \"builtin\"";
  return std::string(kind == Kind::kGarment ? "pattern" : "clip") + " = \"" +
         std::string(name.begin(), name.end()) + "\"";
}

void Export(Catalog& catalog, const EntryInfo& entry, int version, const std::string& out,
            bool force) {
  const costume::catalog::AssetData data = catalog.Data(entry.id, version);
  if (data.format == "builtin") {  // its bytes are only its name: a file of them would mislead
    throw costume::sim::InputError("'" + entry.name + "' (id " + std::to_string(entry.id) +
                                   ") is built into the programs and has no stored file to "
                                   "export; scene files name it (" +
                                   SceneFileReference(entry.kind, data.bytes) +
                                   "), and --thumbnail writes its picture");
  }
  namespace fs = std::filesystem;
  if (costume::catalog::IsBundle(data.bytes)) {  // several files: into the folder `out`
    const auto files = costume::catalog::UnpackBundle(data.bytes, entry.name);
    std::error_code error;
    fs::create_directories(out, error);
    if (error) {
      throw costume::sim::InputError(out + ": cannot create the folder: " + error.message());
    }
    // Every file is checked before any is written: a refusal leaves the folder as it was.
    for (const auto& file : files) {
      if (!force && fs::exists(fs::path(out) / file.name)) {
        throw costume::sim::InputError((fs::path(out) / file.name).string() +
                                       ": already exists (--force replaces it)");
      }
    }
    for (const auto& file : files) {
      WriteOut(fs::path(out) / file.name, file.bytes, true);
      std::printf("wrote %s (%zu bytes)\n", (fs::path(out) / file.name).string().c_str(),
                  file.bytes.size());
    }
    return;
  }
  WriteOut(out, data.bytes, force);
  std::printf("wrote %s: %s '%s' version %d, format %s, %zu bytes\n", out.c_str(),
              KindName(entry.kind), entry.name.c_str(), version ? version : entry.latest_version,
              data.format.c_str(), data.bytes.size());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "costume-catalog: the Costume Designer catalogue of avatars, garments and "
      "animations (docs/catalog.md)."};
  app.require_subcommand(1);
  std::string url = costume::catalog::DefaultCatalogUrl();
  app.add_option("--url", url,
                 "catalogue: sqlite:<path>, a path, or postgresql://... (default: "
                 "$COSTUME_CATALOG, else sqlite:$XDG_DATA_HOME/costume-designer/catalog.sqlite)");
  bool no_thumbnails = false;
  app.add_flag("--no-thumbnails", no_thumbnails,
               "do not render thumbnails (when seeding a new catalogue or importing)");

  costume::catalog::ImportRequest request;
  std::string kind_name;
  auto* import = app.add_subcommand("import", "import avatars, animations or garments from files");
  import->add_option("--kind", kind_name, "avatar | animation | garment")
      ->required()
      ->check(CLI::IsMember({"avatar", "animation", "garment"}));
  import
      ->add_option("--root", request.root,
                   "the import folder: every file must lie inside it (no '..' or symbolic "
                   "links leading out)")
      ->required();
  import
      ->add_option(
          "files", request.files,
          "files to import (MakeHuman avatar: .obj .mhskel .mhw together; garment: .mhclo)")
      ->required();
  import->add_option("--name", request.name, "entry name (one entry only; default: file stem)");
  import->add_option("--category", request.category,
                     "animations: basic (default) | choreography; others: free text");
  import->add_option("--licence", request.licence, "licence of the files")->capture_default_str();
  import->add_option("--provenance", request.provenance,
                     "where the files come from (default: 'imported from <path>')");
  import->add_option("--fabric", request.fabric_preset,
                     "garments: fabric preset cotton | silk | wool | denim | leather (default: "
                     "the garment file's material)");
  import->add_option("--character", request.character,
                     "DeepMimic clips: the character file (default: "
                     "<motion folder>/../characters/humanoid3d.txt)");
  import->add_option("--makehuman-body", request.makehuman_body,
                     "MakeHuman garments (.mhclo): the body they are fitted to (default: "
                     "<garment folder>/../../body/base.obj)");
  import->add_option("--makehuman-skeleton", request.makehuman_skeleton,
                     "MakeHuman garments: the body's skeleton, whose waist holds the "
                     "waistband (default: default.mhskel beside the body)");
  import->add_option("--makehuman-weights", request.makehuman_weights,
                     "MakeHuman garments: the body's skin weights (default: "
                     "default_weights.mhw beside the body)");
  import->add_option("--label", request.label, "garments: the first version's label")
      ->capture_default_str();
  std::uint64_t check_memory_mb = costume::catalog::kDefaultCheckMemoryMb;
  int check_seconds = costume::catalog::kDefaultCheckSeconds;
  // Both import and check load each file or stored version in a child under these limits.
  const auto add_check_limits = [&](CLI::App* command, const std::string& what) {
    command
        ->add_option("--check-memory-mb", check_memory_mb,
                     "memory loading one " + what + " may use; needing more, it is refused "
                     "as damaged [MB]")
        ->check(CLI::Range(std::uint64_t{64}, std::uint64_t{1} << 20))
        ->capture_default_str();
    command
        ->add_option("--check-seconds", check_seconds,
                     "processor time loading one " + what + " may take; needing more, it is "
                     "refused as damaged [s]")
        ->check(CLI::Range(1, 86400))
        ->capture_default_str();
  };
  add_check_limits(import, "file");

  std::string list_kind;
  auto* list = app.add_subcommand("list", "list the entries");
  list->add_option("--kind", list_kind, "avatar | animation | garment (default: all)")
      ->check(CLI::IsMember({"avatar", "animation", "garment"}));

  std::string garment;
  auto* versions = app.add_subcommand("versions", "list a garment's saved versions");
  versions->add_option("garment", garment, "garment name or id")->required();

  std::string export_id;
  int export_version = 0;
  std::string out;
  auto* exporter = app.add_subcommand("export", "write an entry's stored data to a file");
  exporter->add_option("id", export_id, "entry id (or a garment's name)")->required();
  exporter->add_option("--version", export_version, "garment version (default: latest)");
  exporter->add_option("--out", out, "output file (a folder for multi-file entries)")->required();
  bool export_force = false;
  exporter->add_flag("--force", export_force, "replace files that already exist");
  bool export_thumbnail = false;
  exporter->add_flag("--thumbnail", export_thumbnail,
                     "write the entry's thumbnail (PNG) instead of its data");

  std::string remove_id, remove_kind;
  bool remove_yes = false;
  auto* remover = app.add_subcommand(
      "remove", "remove an entry with all its versions (built-in entries stay)");
  remover->add_option("id", remove_id, "entry id, or name with --kind")->required();
  remover->add_option("--kind", remove_kind, "avatar | animation | garment (for a name)")
      ->check(CLI::IsMember({"avatar", "animation", "garment"}));
  remover->add_flag("--yes", remove_yes,
                    "remove it (without: say what would be removed, and remove nothing)");

  auto* checker = app.add_subcommand(
      "check", "check the database and load every version of every entry as an import would");
  add_check_limits(checker, "stored version");

  int thumbnail_size = 128;
  auto* thumbnails = app.add_subcommand(
      "thumbnails",
      "render the thumbnails that are missing: of a catalogue made with --no-thumbnails, or of "
      "garment versions the simulation server saved (it renders none)");
  thumbnails->add_option("--size", thumbnail_size, "width = height [px]")
      ->check(CLI::Range(16, 1024))
      ->capture_default_str();

  CLI11_PARSE(app, argc, argv);
  if (*thumbnails && no_thumbnails) {
    std::cerr << "error: --no-thumbnails contradicts the thumbnails subcommand\n";
    return 2;
  }

  const costume::process::ChildLimits check_limits{.memory_bytes = check_memory_mb << 20,
                                                   .cpu_seconds = check_seconds};
  try {
    costume::catalog::OpenOptions options;
    if (!no_thumbnails) options = costume::catalog::WithRenderedThumbnails();
    const auto catalog = Catalog::Open(url, options);
    if (*import) {
      request.kind = costume::catalog::ParseKind(kind_name);
      request.check_limits = check_limits;
      if (!no_thumbnails) request.thumbnails = costume::catalog::RenderedThumbnails();
      costume::catalog::ImportFiles(*catalog, request, std::cout);
    } else if (*list) {
      if (list_kind.empty()) {
        PrintList(*catalog, {Kind::kAvatar, Kind::kAnimation, Kind::kGarment});
      } else {
        PrintList(*catalog, {costume::catalog::ParseKind(list_kind)});
      }
    } else if (*versions) {
      const EntryInfo entry = Resolve(*catalog, garment, Kind::kGarment);
      const auto history = catalog->Versions(entry.id);  // throws for a non-garment
      std::printf("garment '%s' (id %lld): %d version(s)\n", entry.name.c_str(),
                  static_cast<long long>(entry.id), entry.latest_version);
      for (const auto& v : history) {
        std::printf("  %3d  %s  %s\n", v.version, FormatTime(v.created_utime).c_str(),
                    v.label.c_str());
      }
    } else if (*thumbnails) {
      const int made = catalog->FillMissingThumbnails(costume::catalog::RenderedThumbnails(),
                                                      thumbnail_size, std::cout);
      std::printf("made %d thumbnail(s)\n", made);
    } else if (*checker) {
      const auto problems = costume::catalog::CheckEntries(*catalog, std::cout, check_limits);
      std::printf("%zu problem(s)\n", problems.size());
      if (!problems.empty()) return 1;
    } else if (*remover) {
      Remove(*catalog, remove_id, remove_kind, remove_yes);
    } else if (*exporter) {
      const EntryInfo entry = Resolve(*catalog, export_id, Kind::kGarment);
      if (export_thumbnail) {
        const auto png = catalog->Thumbnail(entry.id);
        if (png.empty()) {
          throw costume::sim::InputError("'" + entry.name + "' has no thumbnail (the "
                                         "thumbnails subcommand makes missing ones)");
        }
        WriteOut(out, png, export_force);
        std::printf("wrote %s (%zu bytes PNG)\n", out.c_str(), png.size());
      } else {
        Export(*catalog, entry, export_version, out, export_force);
      }
    }
  } catch (const costume::sim::InputError& error) {
    std::cerr << "error: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
