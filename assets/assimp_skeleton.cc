#include "assets/assimp_skeleton.h"

#include <Eigen/SVD>
#include <algorithm>
#include <assimp/Importer.hpp>
#include <assimp/scene.h>
#include <cctype>
#include <cmath>
#include <exception>
#include <filesystem>
#include <unordered_set>

#include "assets/assimp_input.h"
#include "assets/import_units.h"
#include "process/limited_child.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {
namespace {

/// A numeric metadata entry of the scene, if present.
std::optional<double> MetadataNumber(const aiScene& scene, const char* key) {
  const aiMetadata* metadata = scene.mMetaData;
  if (metadata == nullptr) return std::nullopt;
  for (unsigned i = 0; i < metadata->mNumProperties; ++i) {
    if (std::string(metadata->mKeys[i].C_Str()) != key) continue;
    const aiMetadataEntry& entry = metadata->mValues[i];
    switch (entry.mType) {
      case AI_INT32: return *static_cast<const int32_t*>(entry.mData);
      case AI_FLOAT: return *static_cast<const float*>(entry.mData);
      case AI_DOUBLE: return *static_cast<const double*>(entry.mData);
      default: return std::nullopt;
    }
  }
  return std::nullopt;
}

void CollectNames(const aiScene& scene, int animation, std::unordered_set<std::string>& names) {
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[m];
    for (unsigned b = 0; b < mesh.mNumBones; ++b) names.insert(mesh.mBones[b]->mName.C_Str());
  }
  if (animation >= 0 && animation < static_cast<int>(scene.mNumAnimations)) {
    const aiAnimation& anim = *scene.mAnimations[animation];
    for (unsigned c = 0; c < anim.mNumChannels; ++c) {
      names.insert(anim.mChannels[c]->mNodeName.C_Str());
    }
  }
}

/// Marks the named nodes, then every node on the path between two marked nodes.
void MarkJointNodes(const aiNode* node, const std::unordered_set<std::string>& names,
                    std::unordered_set<const aiNode*>& marked) {
  if (names.count(node->mName.C_Str())) {
    marked.insert(node);
    std::vector<const aiNode*> between;
    for (const aiNode* up = node->mParent; up != nullptr; up = up->mParent) {
      if (marked.count(up)) {
        marked.insert(between.begin(), between.end());
        break;
      }
      between.push_back(up);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) MarkJointNodes(node->mChildren[c], names, marked);
}

/// Throws for a mesh vertex assimp read as nan or as a number beyond a float's range.
void RefuseNonFiniteVertices(const aiScene& scene, const std::string& path) {
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[m];
    for (unsigned v = 0; mesh.mVertices != nullptr && v < mesh.mNumVertices; ++v) {
      const aiVector3D& p = mesh.mVertices[v];
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) continue;
      throw sim::InputError(path + ": mesh " + std::to_string(m) + " '" +
                            mesh.mName.C_Str() + "' vertex " + std::to_string(v) + " at " +
                            sim::FormatValues({p.x, p.y, p.z}) +
                            " is not a finite point (allowed: finite coordinates)");
    }
  }
}

/// assimp's read with `steps`, null when assimp refuses the file. The steps run after the
/// vertices are checked: JoinIdenticalVertices would merge a vertex read as nan into another
/// one without a word (nan compares equal to everything in its sort). assimp reads the
/// file as assimp_input.h prepares it (a VRM as a GLB, format defaults written out).
const aiScene* ReadChecked(Assimp::Importer& importer, const std::string& path, unsigned steps,
                           const std::string& what) {
  const std::string name = PrepareAssimpInput(importer, path);
  const auto guarded = [&](const auto& call) {
    try {
      return call();
    } catch (const std::exception& e) {
      throw sim::InputError(path + ": cannot read the " + what + ": " + e.what());
    }
  };
  const aiScene* scene = guarded([&] { return importer.ReadFile(name, 0); });
  if (scene == nullptr) return nullptr;
  RefuseNonFiniteVertices(*scene, path);
  return guarded([&] { return importer.ApplyPostProcessing(steps); });
}

/// Reads the file once in a child process under kAssimpReadLimits before this process does: assimp
/// 5.2 crashes on some files (a glTF skin without joints: SIGSEGV; one without inverse bind
/// matrices did before assimp_input.h wrote them out) and allocates without end on others (a
/// Collada index list holding "nan"), which would take the calling program (the simulation server,
/// the GUI) down with it. A file assimp reads or refuses is read again here, for its scene or its
/// own message. Inside a limited child already (the catalogue's import check) no second child is
/// needed.
void ReadInChildFirst(Assimp::Importer& importer, const std::string& path, unsigned steps,
                      const std::string& what) {
  if (process::InLimitedChild()) return;
  const process::ChildResult trial = process::RunLimited(
      [&] {
        ReadChecked(importer, path, steps, what);
        return std::string();
      },
      kAssimpReadLimits);
  using process::ChildEnding;
  if (trial.ending == ChildEnding::kReturned || trial.ending == ChildEnding::kThrew ||
      trial.ending == ChildEnding::kNotStarted) {
    return;
  }
  throw sim::InputError(path + ": cannot read the " + what + ": assimp " +
                        process::DescribeEnding(trial, kAssimpReadLimits,
                                                "the limit for reading one file",
                                                "the limit for reading one file") +
                        " reading it: the file is damaged or uses what this assimp cannot read");
}

}  // namespace

const aiScene* ReadAssimpScene(Assimp::Importer& importer, const std::string& path,
                               unsigned steps, const std::string& what) {
  RequireReadableFile(path, what);
  ReadInChildFirst(importer, path, steps, what);
  const aiScene* scene = ReadChecked(importer, path, steps, what);
  if (scene == nullptr) {
    throw sim::InputError(path + ": cannot read the " + what + ": " + importer.GetErrorString());
  }
  if (scene->mRootNode == nullptr) {
    throw sim::InputError(path + ": cannot read the " + what + ": the scene has no nodes");
  }
  return scene;
}

Eigen::Matrix4d ToEigen(const aiMatrix4x4& m) {
  Eigen::Matrix4d result;
  result << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4, m.d1, m.d2,
      m.d3, m.d4;
  return result;
}

Eigen::Matrix4d GlobalTransform(const aiNode* node) {
  Eigen::Matrix4d global = Eigen::Matrix4d::Identity();
  for (; node != nullptr; node = node->mParent) global = ToEigen(node->mTransformation) * global;
  return global;
}

Eigen::Isometry3d RigidPart(const Eigen::Matrix4d& transform) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(transform.topLeftCorner<3, 3>(),
                                        Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0.0) u.col(2) = -u.col(2);
  Eigen::Isometry3d rigid = Eigen::Isometry3d::Identity();
  rigid.linear() = u * svd.matrixV().transpose();
  rigid.translation() = transform.topRightCorner<3, 1>();
  return rigid;
}

/// glTF (and VRM, a GLB) is in metres with y up by its specification; assimp turns a
/// Collada file's <unit> and <up_axis> into that.
bool MetresYUp(const std::string& extension) {
  return extension == ".gltf" || extension == ".glb" || extension == ".vrm" ||
         extension == ".dae";
}

double DeclaredMetresPerUnit(const aiScene& scene, const std::string& path) {
  const std::string extension = LowerExtension(path);
  if (MetresYUp(extension)) return 1.0;
  if (extension == ".fbx") {
    // FBX: UnitScaleFactor is centimetres per unit (1 when absent, FBX's default cm).
    const double factor = MetadataNumber(scene, "UnitScaleFactor").value_or(1.0);
    return factor > 0.0 && std::isfinite(factor) ? 0.01 * factor : 0.01;
  }
  return 0.0;
}

UpAxis DeclaredUp(const aiScene& scene, const std::string& path) {
  const std::string extension = LowerExtension(path);
  if (MetresYUp(extension)) return UpAxis::kY;
  if (extension == ".fbx") {
    return MetadataNumber(scene, "UpAxis").value_or(1.0) == 2.0 ? UpAxis::kZ : UpAxis::kY;
  }
  return UpAxis::kAuto;
}

Eigen::Matrix4d FileToWorld(double metres_per_unit, UpAxis up) {
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();
  transform.topLeftCorner<3, 3>() = metres_per_unit * UpRotation(up);
  return transform;
}

int AssimpSkeleton::JointAtOrAbove(const aiNode* node) const {
  for (; node != nullptr; node = node->mParent) {
    const auto found = std::find(nodes.begin(), nodes.end(), node);
    if (found != nodes.end()) return static_cast<int>(found - nodes.begin());
  }
  return -1;
}

AssimpSkeleton CollectSkeleton(const aiScene& scene, const Eigen::Matrix4d& file_to_world,
                               int animation) {
  std::unordered_set<std::string> names;
  CollectNames(scene, animation, names);
  std::unordered_set<const aiNode*> marked;
  MarkJointNodes(scene.mRootNode, names, marked);

  AssimpSkeleton skeleton;
  // Depth first, so that parents come before children.
  std::vector<std::pair<const aiNode*, int>> stack = {{scene.mRootNode, -1}};
  while (!stack.empty()) {
    auto [node, parent] = stack.back();
    stack.pop_back();
    if (marked.count(node)) {
      const int index = static_cast<int>(skeleton.joints.size());
      sim::Joint joint;
      joint.name = node->mName.length > 0 ? node->mName.C_Str() : "joint" + std::to_string(index);
      if (skeleton.index_of_name.count(joint.name)) {
        // Appended in two parts: "#" + std::to_string(...) trips GCC 12's -Wrestrict false
        // positive (GCC bug 105329) at -O3.
        joint.name += '#';
        joint.name += std::to_string(index);
      }
      joint.parent = parent;
      const Eigen::Isometry3d world = RigidPart(file_to_world * GlobalTransform(node));
      joint.rest_local = parent < 0 ? world : skeleton.rest_world[parent].inverse() * world;
      skeleton.index_of_name[node->mName.C_Str()] = index;
      skeleton.joints.push_back(std::move(joint));
      skeleton.nodes.push_back(node);
      skeleton.rest_world.push_back(world);
      parent = index;
    }
    for (unsigned c = node->mNumChildren; c-- > 0;) stack.emplace_back(node->mChildren[c], parent);
  }
  return skeleton;
}

}  // namespace costume::assets
