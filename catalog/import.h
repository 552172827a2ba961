#pragma once
/// @file
/// Importing files into the catalogue (what `costume-catalog import` runs): avatars, clips
/// and garments in every format the assets layer reads. Files must lie inside the import
/// folder (--root): a path escaping it, through "..", an absolute path or a symbolic link,
/// is refused. Every file is loaded through its importer (from a private copy of the bytes
/// that will be stored) before anything is written, first in a child process under memory and
/// time limits (a damaged file can make a third-party importer allocate without bound); the
/// entries are then added in one transaction, so a bad file leaves the catalogue unchanged.

#include <cstdint>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "catalog/catalog.h"
#include "catalog/catalog_loader.h"
#include "process/limited_child.h"

namespace costume::catalog {

struct ImportRequest {
  Kind kind = Kind::kAvatar;
  /// The import folder every file must lie in.
  std::string root;
  /// The files (relative to the working directory, or absolute). Avatars: one entry per
  /// file, except MakeHuman's triple (.obj + .mhskel + .mhw given together: one entry).
  /// Animations: .bvh, .glb, .gltf, .fbx, .dae, DeepMimic .txt/.json (its character file is
  /// `character`, else <motion folder>/../characters/humanoid3d.txt). Garments: .toml (a
  /// scene file with one [[garment]]; a mesh file it names is stored with it) or .cdgarment
  /// (an edited garment, assets/edited_garment.h) or MakeHuman's .mhclo (stored with its
  /// garment OBJ and the body it is fitted to: makehuman_body and the two below).
  std::vector<std::string> files;
  /// Entry name (only with one entry); empty: the file name without extension.
  std::string name;
  /// Animations: "basic" (default) or "choreography"; others: free text.
  std::string category;
  std::string licence = "unspecified";
  /// Empty: "imported from <path inside the root>".
  std::string provenance;
  /// Garments: a fabric preset name (fabric_presets.h); empty: the garment file's material.
  std::string fabric_preset;
  /// DeepMimic clips: the character file (inside the root).
  std::string character;
  /// MakeHuman garments: the body they are fitted to (base.obj; default <garment
  /// folder>/../../body/base.obj), its skeleton and skin weights (default default.mhskel and
  /// default_weights.mhw beside the body), all inside the root.
  std::string makehuman_body;
  std::string makehuman_skeleton;
  std::string makehuman_weights;
  /// Garments: the first version's label.
  std::string label = "initial";
  /// Thumbnails (none when empty).
  ThumbnailMaker thumbnails;
  int thumbnail_size = 128;
  /// What checking one file may take: memory beyond the importing process's own, processor
  /// time (`costume-catalog import --check-memory-mb`, `--check-seconds`). A file that needs
  /// more is refused.
  process::ChildLimits check_limits = kDefaultCheckLimits;
};

/// The canonical path of `file` (symbolic links and ".." resolved), which must exist and lie
/// inside `root` (itself canonicalised). Throws sim::InputError naming the file, where it
/// leads and the import folder.
std::filesystem::path ResolveInsideRoot(const std::filesystem::path& root, const std::string& file);

/// Imports `request.files`, printing progress lines to `progress`; returns the new ids.
/// Throws sim::InputError listing every refused file and what is wrong with it (nothing is
/// imported then).
std::vector<std::int64_t> ImportFiles(Catalog& catalog, const ImportRequest& request,
                                      std::ostream& progress);

/// The kind of format a file extension means ("bvh", "glb", ..., "" when unknown).
std::string FormatOfExtension(Kind kind, const std::string& extension);

/// The extensions (lower case, without the dot) of the files ImportFiles takes as `kind`'s
/// entries: every one FormatOfExtension knows, and for avatars MakeHuman's .mhskel and .mhw
/// (picked with its .obj). For a file dialog's filter, so that it offers what the import
/// reads and nothing else.
std::vector<std::string> ImportExtensions(Kind kind);

/// The files of the MakeHuman body a garment's .mhclo is fitted to, when they are picked
/// with it rather than found beside it (ImportRequest::makehuman_body, makehuman_skeleton,
/// makehuman_weights): "obj", "mhskel", "mhw".
const std::vector<std::string>& MakeHumanBodyExtensions();

}  // namespace costume::catalog
