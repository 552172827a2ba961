#pragma once
/// @file
/// glTF skins without inverse bind matrices. glTF 2.0 allows a skin to leave them out (each
/// is then the identity: the joints' bind pose is the mesh's own frame); assimp 5.2 crashes
/// on such a skin (SIGSEGV: it reads the accessor that is not there). The importers hand
/// assimp a copy of the file with those identity matrices written out, read from memory
/// while every other file the glTF names (its .bin, its images) is read from disk.
/// Internal to costume_assets: include only from assets/*.cc.

#include <optional>
#include <string>

#include <assimp/Importer.hpp>

namespace costume::assets {

/// The bytes of a glTF (`binary` false: JSON) or GLB (true) file with an accessor of
/// identity matrices, one per joint, added for every skin that has none; nullopt when every
/// skin has them, or when the bytes are not a glTF this can read (assimp then reads the file
/// as it is and says what is wrong). Throws sim::InputError naming `path` and the skin for a
/// skin whose inverse bind matrices are fewer than its joints (assimp reads past them).
std::optional<std::string> WithExplicitBindMatrices(const std::string& bytes, bool binary,
                                                    const std::string& path);

/// When `path` is a glTF or GLB file that WithExplicitBindMatrices amends, makes `importer`
/// read the amended copy in its place (and the other files from disk); otherwise leaves it
/// alone. Throws as WithExplicitBindMatrices.
void ReadSkinsWithBindMatrices(Assimp::Importer& importer, const std::string& path);

}  // namespace costume::assets
