#pragma once
/// @file
/// DeepMimic reference motions (github.com/xbpeng/DeepMimic, data/motions/*.txt): JSON
/// keyframes of a character described by a separate JSON file (data/characters/*.txt).

#include <memory>
#include <string>

#include "assets/clip_import.h"
#include "sim_core/avatar/skeleton.h"

namespace costume::assets {

/// The character's skeleton (DeepMimic "Skeleton.Joints": ID, Name, Type none|spherical|
/// revolute|fixed, Parent, AttachX/Y/Z [m], AttachThetaX/Y/Z [rad], applied as
/// Rz·Ry·Rx), standing on y = 0: the root is raised so that the lowest point of the
/// "BodyDefs" shapes (box, sphere, capsule; joint positions when there are none) touches
/// the floor. y up; humanoid3d faces +x (its left hip lies at −z). Joints mapped onto
/// H-Anim. `scale` [m per file unit] multiplies every length (DeepMimic uses metres: 1).
/// Throws sim::InputError naming `path` and the field for a malformed file.
std::shared_ptr<const sim::Skeleton> LoadDeepMimicSkeleton(const std::string& path,
                                                           double scale = 1.0);

/// The character file of the motion file `motion`: options.deepmimic_character, or
/// <motion folder>/../characters/humanoid3d.txt (DeepMimic's layout).
std::string DeepMimicCharacterPath(const std::string& motion, const ClipImportOptions& options);

/// Reads a motion file: {"Loop": "wrap"|"none", "Frames": [[dt, root position (3),
/// root rotation quaternion w,x,y,z (4), then per joint in ID order: spherical 4 numbers
/// (quaternion w,x,y,z relative to the parent), revolute 1 (angle about the joint's z
/// axis [rad]), fixed and the root none]]} (44 numbers per frame for humanoid3d).
/// The character file is DeepMimicCharacterPath's. Every frame but the last must have the
/// same dt (> 0, within 1 %): the clip's frame_time. A "wrap" clip loops and its last
/// frame, a copy of the first pose, is dropped. Root rotation goes into the root joint's
/// rotation, root position (minus the rest root position) into root_translation.
/// Throws sim::InputError naming `path`, the frame and the field.
sim::Clip LoadDeepMimicClip(const std::string& path, const ClipImportOptions& options);

}  // namespace costume::assets
