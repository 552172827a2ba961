#pragma once
/// @file
/// Reading animation clips (BVH, glTF/GLB, FBX, Collada, DeepMimic JSON) into sim::Clip:
/// poses of the file's own skeleton, in metres, y up, with the joints mapped onto H-Anim
/// (skeleton_families.h) so that sim::Retargeter can put the clip on any avatar.

#include <optional>
#include <string>

#include "assets/import_units.h"
#include "sim_core/avatar/clip.h"

namespace costume::assets {

/// How a clip file is read. The defaults suit the files in ../shared/data.
struct ClipImportOptions {
  /// Metres per file unit, 0 to detect: glTF metres; Collada its <unit> (applied by
  /// assimp); FBX its UnitScaleFactor (cm × factor); DeepMimic metres; BVH says nothing,
  /// so the unit is guessed from the skeleton's rest height (GuessMetresPerUnit: CMU 02_02
  /// comes out in cm, CMU 10_01 in inches, MakeHuman's BVH in dm). Else finite and > 0.
  double scale = 0.0;
  /// Which file axis is up (see UpAxis).
  UpAxis up = UpAxis::kAuto;
  /// Sampling rate for keyframed animations (glTF, FBX, Collada) [Hz], in [1, 1000].
  double sample_rate = 30.0;
  /// Which animation of a multi-animation file (glTF, FBX, Collada), from 0.
  int animation = 0;
  /// Whether the clip loops; nullopt: DeepMimic's "Loop" field; for keyframed animations,
  /// whether the pose at the end matches the pose at the start (joint rotations within
  /// 10°, root within 5 cm); BVH: false.
  std::optional<bool> loops;
  /// Shift the root's horizontal path so that the first frame stands over the rest
  /// root position (mocap files start wherever the actor stood in the studio).
  bool start_at_origin = true;
  sim::ClipCategory category = sim::ClipCategory::kBasic;
  /// The clip's name; empty: the file name without extension.
  std::string name;
  /// DeepMimic only: the character file with the skeleton; empty:
  /// <motion folder>/../characters/humanoid3d.txt.
  std::string deepmimic_character;
};

/// Reads the clip in `path`, choosing the reader by extension: .bvh (own parser: any
/// channel order, position channels on the root), .txt/.json (DeepMimic, see
/// deepmimic_import.h), anything else through assimp (.gltf, .glb, .fbx, .dae). The clip's
/// skeleton is the file's, its rest pose standing on y = 0 for BVH and DeepMimic (the
/// file's own placement for the others), joints mapped onto H-Anim by the detected
/// family; Pose::rotations are relative to the rest frames, Pose::root_translation the
/// root's offset from its rest position [m]. The clip is validated (sim::ValidateClip).
/// Throws sim::InputError naming `path` (and the line or field where known) for a missing,
/// truncated or malformed file, a file without animation, options out of range.
sim::Clip LoadClip(const std::string& path, const ClipImportOptions& options = {});

/// Throws sim::InputError naming `path` for options out of range.
void ValidateClipOptions(const std::string& path, const ClipImportOptions& options);

/// Applies ClipImportOptions::start_at_origin to `clip` (subtracts the first frame's
/// horizontal root translation from every frame).
void MoveStartToOrigin(sim::Clip& clip);

}  // namespace costume::assets
