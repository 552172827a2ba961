#pragma once
/// @file
/// Turning catalogue entries into simulation inputs, through the importers of assets/ (the
/// bytes are written to a private temporary folder when an importer needs a path).

#include <cstdint>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "catalog/catalog.h"
#include "process/limited_child.h"
#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/scene_description.h"

namespace costume::catalog {

/// The avatar of entry `id` (kind avatar). Throws sim::InputError naming the entry for a
/// wrong kind or data its importer refuses.
std::shared_ptr<const sim::Avatar> LoadAvatar(Catalog& catalog, std::int64_t id);

/// The clip of entry `id` (kind animation), with the entry's category, on its own skeleton:
/// built-in clips on the built-in humanoid's, whose world-aligned rest frames their angles
/// are written for; clips from files on the file's. sim::Retargeter (AvatarMotion) puts
/// either on any avatar. Throws sim::InputError.
std::shared_ptr<const sim::Clip> LoadClip(Catalog& catalog, std::int64_t id);

/// Version `version` (0: latest) of garment `id` as a scene garment named after the entry.
/// Its `material` names the entry's fabric as GarmentMaterial returns it ("<name>_fabric"),
/// which must be added to the scene's materials (AddGarmentToScene does both). Built-in
/// patterns need the scene to have an avatar; edited garments carry their prebuilt model
/// (GarmentSpec::model). Throws sim::InputError naming the entry and version.
sim::GarmentSpec LoadGarment(Catalog& catalog, std::int64_t id, int version = 0);

/// The body garment `id` was made for (GarmentSpec::made_for): for a MakeHuman garment its
/// first version's body, which its saved edits (prebuilt models) are worn by too; else null.
std::shared_ptr<const sim::Avatar> MadeForBody(Catalog& catalog, std::int64_t id);

/// The fabric of garment `id` as a sim::Material named "<entry name>_fabric".
sim::Material GarmentMaterial(Catalog& catalog, std::int64_t id);

/// Appends version `version` of garment `id` and its material to `scene` (a material of the
/// same name already there is replaced). A garment made for one body (a MakeHuman garment,
/// GarmentSpec::made_for) brings that body as the scene's avatar when the avatar is another
/// (the clip stays; a posture for another skeleton is dropped): returns true then.
bool AddGarmentToScene(Catalog& catalog, std::int64_t id, int version,
                       sim::SceneDescription& scene);

/// A "makehuman-garment" bundle holds, under their own file names, the .mhclo, the garment
/// OBJ its obj_file line names, and the MakeHuman body it is fitted to: the other .obj (its
/// base.obj), a .mhskel and a .mhw. The garment loads as assets::MakeHumanGarmentSpec makes
/// it and is worn by that body only (GarmentSpec::made_for; its thumbnail shows it on that
/// body).

/// Limits for loading one file (an import) or one stored version (a check) in a child
/// process (`--check-memory-mb`, `--check-seconds`): the real assets of ../shared/data need
/// under 0.12 GB and 0.3 s each; a 1 KB Collada file with "nan" among its indices makes
/// assimp 5.2 allocate without end.
inline constexpr std::uint64_t kDefaultCheckMemoryMb = 4096;
inline constexpr int kDefaultCheckSeconds = 300;
inline constexpr process::ChildLimits kDefaultCheckLimits{
    .memory_bytes = kDefaultCheckMemoryMb << 20, .cpu_seconds = kDefaultCheckSeconds};

/// Runs `check` in a child process under `limits` (process/limited_child.h), so that bytes
/// which make an importer crash or allocate without bound cost this process nothing; where
/// no child can be made, runs it here. Throws sim::InputError with the child's refusal, or
/// naming `what`, the limit it hit (`--check-memory-mb`, `--check-seconds`) and "the
/// `subject` is likely damaged". What `check` changes stays in the child, unless it ran here.
void CheckInChild(const std::function<void()>& check, const process::ChildLimits& limits,
                  const std::string& what, const std::string& subject);

/// What messages call a stored DeepMimic clip's character file (after the clip's own name):
/// the character is kept in the clip's bundle, its file name lost.
inline constexpr const char* kCharacterFileLabel = "its character file";

/// Checks that `data` loads as an entry of `kind` (what Catalog users import), returning the
/// request a ThumbnailMaker needs to draw it. Throws sim::InputError naming `what` (a file
/// name) and the problem; a DeepMimic clip's character file is named `character_what` (the
/// importer passes the user's path). `fabric` is the garment's fabric (ignored for other
/// kinds); `made_for`, the body a garment whose data does not name one was made for
/// (MadeForBody: a saved edit of a MakeHuman garment), which it is checked and drawn on.
ThumbnailRequest CheckAssetData(Kind kind, const std::string& name, const AssetData& data,
                                const FabricParameters& fabric, const std::string& what,
                                const std::string& character_what = kCharacterFileLabel,
                                std::shared_ptr<const sim::Avatar> made_for = nullptr);

/// CheckAssetData on version `version` (0: latest) of `entry` as stored, named `what`: a
/// saved edit of a MakeHuman garment is checked on its body (MadeForBody).
ThumbnailRequest CheckStoredVersion(Catalog& catalog, const EntryInfo& entry, int version,
                                    const std::string& what);

/// Checks the whole catalogue as imports check a new file: Catalog::CheckIntegrity, then
/// every version of every entry loaded (CheckAssetData: an importer's refusal, a clip no
/// avatar can play, a garment whose cloth cannot be built). Entries stored by older builds
/// may fail checks added since. Each version is loaded in a child process under `limits`
/// (process/limited_child.h): stored bytes damaged after their import (a damaged database,
/// another program's writes) can make an importer crash or allocate without bound, and are
/// then reported as damaged. Writes a line per entry and version to `log` ("...: ok", or
/// "...: refused" and the problem on the next line) and returns the problems (empty: all
/// sound).
std::vector<std::string> CheckEntries(Catalog& catalog, std::ostream& log,
                                      const process::ChildLimits& limits = kDefaultCheckLimits);

}  // namespace costume::catalog
