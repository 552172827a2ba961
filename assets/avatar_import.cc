#include "assets/avatar_import.h"

#include <Eigen/SVD>
#include <algorithm>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cmath>
#include <filesystem>
#include <utility>
#include <vector>

#include "assets/assimp_skeleton.h"
#include "assets/skeleton_families.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {
namespace {

using sim::InputError;

/// Attributes a collision surface does not use; dropping them lets JoinIdenticalVertices
/// join the copies a UV seam or a hard edge makes of one point.
constexpr int kDroppedComponents = aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                   aiComponent_COLORS | aiComponent_TEXCOORDS |
                                   aiComponent_MATERIALS;

constexpr unsigned kSteps = aiProcess_Triangulate | aiProcess_RemoveComponent |
                            aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure;

using Influences = std::vector<std::pair<int, double>>;

/// The merged surface while it is gathered, in the file's units taken through
/// `file_to_world` (so metres and y up).
struct Surface {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Influences> influences;
};

/// Below this ratio of its smallest to its largest singular value a bone's inverse bind
/// matrix is singular: it folds the skin it holds onto a plane, a line or a point.
constexpr double kMinBindConditioning = 1e-9;

/// Throws InputError naming the file, the bone and the mesh unless the bone's inverse bind
/// matrix (aiBone::mOffsetMatrix) can be inverted: a singular one puts every vertex it holds
/// in one place, and the avatar was stored invisible.
void RequireInvertibleBind(const std::string& path, const aiMesh& mesh, const aiBone& bone) {
  const Eigen::Vector3d singular =
      ToEigen(bone.mOffsetMatrix).topLeftCorner<3, 3>().jacobiSvd().singularValues();
  if (singular.allFinite() && singular.minCoeff() > kMinBindConditioning * singular.maxCoeff()) {
    return;
  }
  throw InputError(path + ": bone '" + bone.mName.C_Str() + "' of mesh '" + mesh.mName.C_Str() +
                   "': its inverse bind matrix is singular (singular values " +
                   sim::FormatValue(singular.maxCoeff()) + " to " +
                   sim::FormatValue(singular.minCoeff()) +
                   "; allowed: the smallest above " + sim::FormatValue(kMinBindConditioning) +
                   " times the largest), so it would put the skin it holds in one place");
}

Eigen::Vector3d Transform(const Eigen::Matrix4d& m, const aiVector3D& v) {
  return (m * Eigen::Vector4d(v.x, v.y, v.z, 1.0)).head<3>();
}

/// Adds one mesh placed by its node (or, for skinned vertices, by its bones' bind
/// matrices in the nodes' default pose).
void AddMesh(const std::string& path, const aiMesh& mesh, const aiNode* node,
             const Eigen::Matrix4d& file_to_world, const AssimpSkeleton& skeleton,
             Surface& surface) {
  const int base = static_cast<int>(surface.vertices.size());
  const Eigen::Matrix4d node_to_world = file_to_world * GlobalTransform(node);
  std::vector<Eigen::Vector3d> weighted(mesh.mNumVertices, Eigen::Vector3d::Zero());
  std::vector<double> total(mesh.mNumVertices, 0.0);
  std::vector<Influences> influences(mesh.mNumVertices);
  for (unsigned b = 0; b < mesh.mNumBones; ++b) {
    const aiBone& bone = *mesh.mBones[b];
    const auto joint = skeleton.index_of_name.find(bone.mName.C_Str());
    if (joint == skeleton.index_of_name.end()) {
      throw InputError(path + ": bone '" + bone.mName.C_Str() + "' of mesh '" +
                       mesh.mName.C_Str() + "' has no node");
    }
    RequireInvertibleBind(path, mesh, bone);
    const Eigen::Matrix4d bind = file_to_world *
                                 GlobalTransform(skeleton.nodes[joint->second]) *
                                 ToEigen(bone.mOffsetMatrix);
    for (unsigned w = 0; w < bone.mNumWeights; ++w) {
      const aiVertexWeight& weight = bone.mWeights[w];
      if (weight.mVertexId >= mesh.mNumVertices || !(weight.mWeight >= 0.0f)) {
        throw InputError(path + ": bone '" + bone.mName.C_Str() + "' weight " +
                         std::to_string(w) + " (vertex " + std::to_string(weight.mVertexId) +
                         ", weight " + sim::FormatValue(weight.mWeight) + ") out of range");
      }
      if (weight.mWeight == 0.0f) continue;
      weighted[weight.mVertexId] += weight.mWeight * Transform(bind, mesh.mVertices[weight.mVertexId]);
      total[weight.mVertexId] += weight.mWeight;
      influences[weight.mVertexId].emplace_back(joint->second, weight.mWeight);
    }
  }
  const int holder = std::max(0, skeleton.JointAtOrAbove(node));
  for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
    if (total[v] > 0.0) {
      surface.vertices.push_back(weighted[v] / total[v]);
      surface.influences.push_back(std::move(influences[v]));
    } else {
      surface.vertices.push_back(Transform(node_to_world, mesh.mVertices[v]));
      surface.influences.push_back({{holder, 1.0}});
    }
  }
  const bool mirrored = node_to_world.topLeftCorner<3, 3>().determinant() < 0.0;
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    if (face.mNumIndices != 3) continue;  // points and lines left by Triangulate
    Eigen::Vector3i triangle(base + face.mIndices[0], base + face.mIndices[1],
                             base + face.mIndices[2]);
    if (mirrored) std::swap(triangle[1], triangle[2]);
    surface.triangles.push_back(triangle);
  }
}

void AddNodeMeshes(const std::string& path, const aiScene& scene, const aiNode* node,
                   const Eigen::Matrix4d& file_to_world, const AssimpSkeleton& skeleton,
                   Surface& surface) {
  for (unsigned m = 0; m < node->mNumMeshes; ++m) {
    AddMesh(path, *scene.mMeshes[node->mMeshes[m]], node, file_to_world, skeleton, surface);
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) {
    AddNodeMeshes(path, scene, node->mChildren[c], file_to_world, skeleton, surface);
  }
}

/// The height of everything the scene's meshes hold, in file units turned y up.
double MeshHeight(const aiScene& scene, const aiNode* node, const Eigen::Matrix4d& rotate,
                  double& lowest, double& highest) {
  const Eigen::Matrix4d to_world = rotate * GlobalTransform(node);
  for (unsigned m = 0; m < node->mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[node->mMeshes[m]];
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const double y = Transform(to_world, mesh.mVertices[v]).y();
      lowest = std::min(lowest, y);
      highest = std::max(highest, y);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) {
    MeshHeight(scene, node->mChildren[c], rotate, lowest, highest);
  }
  return highest - lowest;
}

/// Keeps the kMaxInfluences largest weights (one entry per joint) and renormalises.
void FillInfluences(const std::vector<Influences>& all, sim::AvatarData& data) {
  const Eigen::Index n = static_cast<Eigen::Index>(all.size());
  data.influence_joints.setConstant(n, sim::kMaxInfluences, -1);
  data.influence_weights.setZero(n, sim::kMaxInfluences);
  for (Eigen::Index v = 0; v < n; ++v) {
    Influences merged;
    for (const auto& [joint, weight] : all[v]) {
      auto same = std::find_if(merged.begin(), merged.end(),
                               [&](const auto& entry) { return entry.first == joint; });
      if (same == merged.end()) {
        merged.emplace_back(joint, weight);
      } else {
        same->second += weight;
      }
    }
    std::sort(merged.begin(), merged.end(),
              [](const auto& a, const auto& b) { return a.second > b.second; });
    merged.resize(std::min<std::size_t>(merged.size(), sim::kMaxInfluences));
    double sum = 0.0;
    for (const auto& entry : merged) sum += entry.second;
    for (std::size_t k = 0; k < merged.size(); ++k) {
      data.influence_joints(v, static_cast<Eigen::Index>(k)) = merged[k].first;
      data.influence_weights(v, static_cast<Eigen::Index>(k)) = merged[k].second / sum;
    }
  }
}

std::vector<sim::Joint> StaticSkeleton() {
  sim::Joint root;
  root.name = "root";
  root.hanim = sim::HAnimJoint::kHumanoidRoot;
  return {root};
}

/// The quarter turns about +y (0 to 3) that make a character face +z, its left hip at +x
/// of its right one (the results' convention, which the built-in garments and the camera
/// assume): the quarter turn nearest the exact one. 0 without both hips mapped, or when
/// they lie more above each other than side by side (a body not standing up).
int QuarterTurnsToFaceZ(const sim::Skeleton& skeleton) {
  const int left = skeleton.Find(sim::HAnimJoint::kLHip);
  const int right = skeleton.Find(sim::HAnimJoint::kRHip);
  if (left < 0 || right < 0) return 0;
  const Eigen::Vector3d across =
      skeleton.rest_world()[left].translation() - skeleton.rest_world()[right].translation();
  if (!(std::hypot(across.x(), across.z()) > std::abs(across.y()))) return 0;
  // Turning by θ about +y takes (x, z) to (x cos θ + z sin θ, −x sin θ + z cos θ).
  const double quarters = std::atan2(across.z(), across.x()) / (0.5 * M_PI);
  return static_cast<int>(std::lround(quarters) + 4) % 4;
}

/// Turns the avatar `turns` quarter turns about +y: its root joints and its vertices.
void TurnAboutY(int turns, std::vector<sim::Joint>& joints, sim::Points& vertices) {
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(turns * 0.5 * M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  for (sim::Joint& joint : joints) {
    if (joint.parent < 0) joint.rest_local = Eigen::Isometry3d(turn) * joint.rest_local;
  }
  vertices = vertices * turn.transpose();
}

}  // namespace

std::shared_ptr<const sim::Avatar> LoadAvatar(const std::string& path,
                                              const AvatarImportOptions& options) {
  ValidateScaleOption(path, options.scale);
  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, kDroppedComponents);
  const aiScene* scene = ReadAssimpScene(importer, path, kSteps, "avatar file");
  if (scene->mNumMeshes == 0) throw InputError(path + ": the avatar file holds no meshes");

  UpAxis up = options.up != UpAxis::kAuto ? options.up : DeclaredUp(*scene, path);
  if (up == UpAxis::kAuto) up = UpAxis::kY;
  double scale = options.scale > 0.0 ? options.scale : DeclaredMetresPerUnit(*scene, path);
  if (scale <= 0.0) {
    double lowest = INFINITY, highest = -INFINITY;
    scale = GuessMetresPerUnit(
        MeshHeight(*scene, scene->mRootNode, FileToWorld(1.0, up), lowest, highest));
  }
  const Eigen::Matrix4d file_to_world = FileToWorld(scale, up);

  AssimpSkeleton skeleton = CollectSkeleton(*scene, file_to_world, -1);
  Surface surface;
  AddNodeMeshes(path, *scene, scene->mRootNode, file_to_world, skeleton, surface);
  if (surface.triangles.empty()) throw InputError(path + ": the avatar file holds no triangles");

  sim::AvatarData data;
  data.name = options.name.empty() ? std::filesystem::path(path).stem().string() : options.name;
  data.provenance = path;
  std::vector<sim::Joint> joints = std::move(skeleton.joints);
  if (joints.empty()) {
    joints = StaticSkeleton();
  } else {
    MapToHAnim(joints);
  }
  data.rest_vertices.resize(static_cast<Eigen::Index>(surface.vertices.size()), 3);
  for (std::size_t v = 0; v < surface.vertices.size(); ++v) {
    data.rest_vertices.row(static_cast<Eigen::Index>(v)) = surface.vertices[v].transpose();
  }
  try {
    data.skeleton = sim::Skeleton::Create(data.name, joints);
    // A file whose character faces another way than +z (a VRM 0.x faces −z) is turned to
    // face it, so garments go on with their fronts to its front.
    if (const int turns = QuarterTurnsToFaceZ(*data.skeleton); turns != 0) {
      TurnAboutY(turns, joints, data.rest_vertices);
      data.skeleton = sim::Skeleton::Create(data.name, std::move(joints));
    }
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
  data.triangles = std::move(surface.triangles);
  FillInfluences(surface.influences, data);
  try {
    return sim::Avatar::Create(std::move(data));
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

}  // namespace costume::assets
