#pragma once
/// @file
/// Defaults of the file formats that assimp 5.2 does not apply, written out into the copy of
/// the file it reads (from memory, while every other file the scene names, a .bin or an
/// image, is read from disk):
/// - a glTF 2.0 skin may leave out its inverse bind matrices (each is then the identity: the
///   joints' bind pose is the mesh's own frame); assimp crashes on such a skin (SIGSEGV: it
///   reads the accessor that is not there);
/// - a COLLADA 1.4 skin may leave out its <bind_shape_matrix> (the identity); assimp takes a
///   zero matrix, which puts the whole skin at one point.
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

/// The text of a COLLADA file with an identity <bind_shape_matrix> as the first child of
/// every <skin> that has none; nullopt when every skin has one.
std::optional<std::string> WithExplicitBindShapes(const std::string& text);

/// When `path` is a glTF, GLB or COLLADA file that the functions above amend, makes
/// `importer` read the amended copy in its place (and the other files from disk); otherwise
/// leaves it alone. Throws as WithExplicitBindMatrices.
void ReadWithExplicitDefaults(Assimp::Importer& importer, const std::string& path);

}  // namespace costume::assets
