#pragma once
/// @file
/// What the avatar and clip importers share when reading through assimp: the scene, the
/// file's declared units and up axis, and the skeleton made of the scene's bone nodes.
/// Internal to costume_assets (which links assimp privately): include only from assets/*.cc.

#include <Eigen/Geometry>
#include <string>
#include <unordered_map>
#include <vector>

#include "assets/import_units.h"
#include "process/limited_child.h"
#include "sim_core/avatar/skeleton.h"

#include <assimp/Importer.hpp>
#include <assimp/scene.h>

namespace costume::assets {

/// What assimp may take reading one file, in a child process first (ReadAssimpScene): the
/// real assets of ../shared/data need under 0.12 GB and 0.3 s each.
inline constexpr process::ChildLimits kAssimpReadLimits{.memory_bytes = std::uint64_t{4096} << 20,
                                                        .cpu_seconds = 300};

/// Reads `path` with `importer` and post-processing `steps`, first in a child process under
/// kAssimpReadLimits. Throws sim::InputError naming `path` for a missing or unreadable file,
/// a file assimp refuses (quoting assimp's error), reads only partly, crashes on or needs more
/// than the limits for, and a mesh vertex that is not a finite point. `what` names the kind
/// of file in messages ("avatar file").
const aiScene* ReadAssimpScene(Assimp::Importer& importer, const std::string& path,
                               unsigned steps, const std::string& what);

/// assimp's row-major matrix as Eigen's.
Eigen::Matrix4d ToEigen(const aiMatrix4x4& m);

/// The node's transform to the scene root's frame (file units, may hold scale).
Eigen::Matrix4d GlobalTransform(const aiNode* node);

/// The rigid part of an affine transform: its translation and the rotation nearest its
/// linear part (polar decomposition; a mirror is turned into the nearest rotation).
Eigen::Isometry3d RigidPart(const Eigen::Matrix4d& transform);

/// Metres per file unit the file declares (glTF 1; Collada 1 since assimp applies
/// <unit>; FBX UnitScaleFactor × 0.01), or 0 when the format declares none.
double DeclaredMetresPerUnit(const aiScene& scene, const std::string& path);

/// The up axis the file declares (glTF, Collada: y after assimp's conversion; FBX: its
/// UpAxis property), kAuto when the format declares none.
UpAxis DeclaredUp(const aiScene& scene, const std::string& path);

/// The joints of a scene: the nodes named by mesh bones or animation channels, plus any
/// node between two of them, in depth-first order. Rest frames are the nodes' default
/// transforms, taken through `file_to_world` (scale and up rotation) and made rigid.
struct AssimpSkeleton {
  std::vector<sim::Joint> joints;
  /// The node of each joint.
  std::vector<const aiNode*> nodes;
  /// Each joint's rest frame in world coordinates [m].
  std::vector<Eigen::Isometry3d> rest_world;
  /// Joint index by node name.
  std::unordered_map<std::string, int> index_of_name;
  /// The joint index of `node` or of its nearest joint ancestor, -1 if none.
  int JointAtOrAbove(const aiNode* node) const;
};

/// Builds the skeleton (joints not yet mapped onto H-Anim). `animation` < 0: channels of no
/// animation count. Empty when the scene has no bones and no animated nodes.
AssimpSkeleton CollectSkeleton(const aiScene& scene, const Eigen::Matrix4d& file_to_world,
                               int animation);

/// scale × rotation, as a 4×4 transform.
Eigen::Matrix4d FileToWorld(double metres_per_unit, UpAxis up);

}  // namespace costume::assets
