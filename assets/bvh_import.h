#pragma once
/// @file
/// Biovision BVH motion files (own parser: assimp's BVH reader loses the channel order).

#include <string>

#include "assets/clip_import.h"

namespace costume::assets {

/// Reads a BVH file into a clip (see LoadClip for units, axes and the rest pose).
/// - Rotation channels in any order: the joint's rotation is the product of the channels
///   in the order listed (Zrotation Xrotation Yrotation → Rz·Rx·Ry), in degrees.
/// - Position channels are honoured on root joints (absolute positions, as CMU and
///   MakeHuman write them); on other joints they are ignored (a rigid skeleton keeps its
///   bone lengths).
/// - Several ROOTs are allowed; End Sites count for the rest height, they are not joints.
/// Limits: at most 10,000 joints, 1..10,000,000 frames, frame time in (0, 10] s.
/// Throws sim::InputError naming `path` and the line for a malformed, truncated or
/// out-of-range file.
sim::Clip LoadBvhClip(const std::string& path, const ClipImportOptions& options);

}  // namespace costume::assets
