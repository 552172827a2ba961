#pragma once
/// @file
/// Units and axes shared by the avatar and clip importers: every imported skeleton, mesh and
/// clip ends up in metres, y up, and (where the file says which way the body faces) facing +z.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace costume::assets {

/// Which file axis points up.
enum class UpAxis {
  /// The file's declaration (glTF: y; Collada: its up_axis, applied by assimp; FBX: its
  /// UpAxis property), else guessed (BVH: the axis from the root to the head), else y.
  kAuto,
  kY,
  /// z up, y back (Blender, 3ds Max, MakeHuman's BVH): converted by a −90° turn about x,
  /// so file +z becomes +y and file −y becomes +z.
  kZ,
};

/// The rotation taking file coordinates with `up` (kY or kZ) to y-up coordinates.
Eigen::Matrix3d UpRotation(UpAxis up);

/// Metres per file unit guessed from a humanoid's height in file units: the unit among
/// m, dm, cm, mm and inch that makes the height closest (in ratio) to 1.7 m. Returns 1 for
/// a height that is not finite and > 0.
double GuessMetresPerUnit(double height_in_file_units);

/// Throws sim::InputError naming `path` and the field "scale" unless `scale` is 0 (detect)
/// or finite and > 0 [m per file unit].
void ValidateScaleOption(const std::string& path, double scale);

/// Throws sim::InputError naming `path`, `what` ("mesh file") and the reason unless `path` is
/// a regular file that can be opened.
void RequireReadableFile(const std::string& path, const std::string& what);

/// The file name's extension with its dot, in lower case ("model.GLB" -> ".glb"; "" for none):
/// what the importers pick a format by.
std::string LowerExtension(const std::string& path);

/// The whole file as a string; throws sim::InputError naming `path` if it cannot be read.
std::string ReadWholeFile(const std::string& path, const std::string& what);

}  // namespace costume::assets
