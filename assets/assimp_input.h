#pragma once
/// @file
/// What the importers hand assimp 5.2 in place of a file (read from memory, while every
/// other file the scene names, a .bin or an image, is read from disk): a VRM avatar (VRoid
/// Studio's) as the GLB it is, which assimp reads only by that name; and the defaults of the
/// file formats that assimp does not apply, written out:
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

/// Makes `importer` read the copy of `path` the functions above amend, if any, in its place
/// (and the other files from disk). Returns the name to hand to Importer::ReadFile: `path`,
/// or for a VRM `path` + ".glb", under which the importer finds the VRM's bytes. Throws as
/// WithExplicitBindMatrices.
std::string PrepareAssimpInput(Assimp::Importer& importer, const std::string& path);

}  // namespace costume::assets
