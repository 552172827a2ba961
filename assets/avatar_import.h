#pragma once
/// @file
/// Reading skinned avatars (glTF/GLB, FBX, Collada) and static ones (OBJ, or any mesh file
/// without bones) through assimp into sim::Avatar. MakeHuman's body + skeleton + weights
/// triple has its own reader (makehuman_import.h).

#include <memory>
#include <string>

#include "assets/import_units.h"
#include "sim_core/avatar/avatar.h"

namespace costume::assets {

struct AvatarImportOptions {
  /// Metres per file unit, 0 to detect: glTF metres; Collada its <unit> (applied by
  /// assimp); FBX its UnitScaleFactor (cm × factor); formats that declare nothing (OBJ) are
  /// guessed from the body's height (GuessMetresPerUnit). Else finite and > 0.
  double scale = 0.0;
  /// Which file axis is up (see UpAxis); kAuto: the file's declaration, else y.
  UpAxis up = UpAxis::kAuto;
  /// The avatar's name; empty: the file name without extension.
  std::string name;
};

/// Reads the avatar in `path`:
/// - skeleton: the nodes named by the meshes' bones (and any node between two of them), in
///   depth-first order; rest frames from the node transforms, made rigid (any scale in
///   the node transforms ends up in the vertex positions instead); joints mapped onto
///   H-Anim by the detected skeleton family (skeleton_families.h);
/// - surface: every mesh of the scene merged, triangulated, vertices joined by position,
///   placed in the rest pose as the file's bind matrices put them, in metres, y up;
/// - skin: each vertex keeps its 4 largest bone weights, renormalised to sum 1; vertices
///   of meshes without bones (and unweighted vertices) follow the joint at or above their
///   node, else the first root;
/// - a file without bones (OBJ) gives a static avatar: one joint "root" at the origin
///   carrying every vertex;
/// - facing +z (its left hip at +x of its right one): an avatar facing another way in its
///   file is turned about y by the nearest quarter turn that makes it face +z.
/// Throws sim::InputError naming `path` for: options out of range, a missing, unreadable,
/// truncated or malformed file (quoting assimp), a file without triangles, and whatever
/// sim::Avatar::Create refuses.
std::shared_ptr<const sim::Avatar> LoadAvatar(const std::string& path,
                                              const AvatarImportOptions& options = {});

}  // namespace costume::assets
