#pragma once
/// @file
/// Scene files: the human-editable TOML format of docs/scene_format.md, parsed into
/// sim::SceneDescription, and the built-in scenes (scenes/*.toml, compiled into the
/// program so that it needs no data file at run time).
///
/// Every refusal is an sim::InputError whose message points at the place to fix:
///   `<file>:<line>:<column>: <table>.<field> = <value> <unit>: <what is wrong, allowed range>`
/// e.g. `scenes/hang.toml:14:1: material[0].density = -1 kg/m²: must be a finite number > 0`.

#include <string>
#include <vector>

#include "sim_core/scene/scene_description.h"

namespace costume::assets {

/// Whether `[avatar]` may name avatar and clip files. The catalogue's garment files may not:
/// a garment entry holds its own files only (its mesh), avatars and animations are entries
/// of their own, and a path stored in the database would be read wherever it is loaded.
enum class AvatarFiles { kAllowed, kRefused };

/// Reads and parses the scene file at `path` (see ParseSceneText). Mesh, avatar and clip
/// files named in it are relative to the scene file's folder. Throws sim::InputError when
/// the file cannot be read or is refused.
sim::SceneDescription LoadSceneFile(const std::string& path,
                                    AvatarFiles avatar_files = AvatarFiles::kAllowed);

/// Parses scene text in the format of docs/scene_format.md and checks it.
/// `source_name` is quoted at the start of error messages and stored as the scene's
/// `source`; `base_dir` is the folder relative file paths start from (the scene file's
/// folder; "" means the working directory). Mesh garments, and the avatar and clip files
/// `[avatar]` names, are read here, so the result is complete. The returned scene passes
/// sim::ValidateScene. Throws sim::InputError, with file:line:column, for: TOML syntax
/// errors; unknown keys (listing the allowed ones); values of the wrong type or shape;
/// nan, inf and out-of-range numbers; missing required keys or tables; duplicate material or
/// garment names; a garment naming an unknown material (listing the known ones); a garment
/// with both or neither of panel and mesh; a mesh file that cannot be imported.
sim::SceneDescription ParseSceneText(const std::string& text, const std::string& source_name,
                                     const std::string& base_dir,
                                     AvatarFiles avatar_files = AvatarFiles::kAllowed);

/// Names of the built-in scenes: "demo" (the default run), "hang" and "drape" (the
/// benchmark scenes of docs/BENCHMARKS.md at N = 33).
std::vector<std::string> BuiltInSceneNames();

/// TOML text of a built-in scene, identical to scenes/<name>.toml when the program was
/// built. Throws sim::InputError for an unknown name, listing the known ones.
std::string BuiltInSceneText(const std::string& name);

/// Parses a built-in scene; its source is "built-in:<name>". Throws sim::InputError for an
/// unknown name, listing the known ones.
sim::SceneDescription LoadBuiltInScene(const std::string& name);

}  // namespace costume::assets
