#include "assets/mesh_import.h"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <utility>
#include <vector>

#include "assets/assimp_skeleton.h"
#include "assets/import_units.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {

namespace {

using sim::InputError;

/// Vertex attributes we never use; dropping them lets JoinIdenticalVertices join vertices
/// that differ only in normals or texture coordinates.
constexpr int kDroppedComponents = aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                   aiComponent_COLORS | aiComponent_TEXCOORDS |
                                   aiComponent_BONEWEIGHTS;

/// No aiProcess_Triangulate: quads must survive to become shear diagonals (mesh_cloth.h).
constexpr unsigned kPostProcessSteps =
    aiProcess_RemoveComponent | aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure;

void ValidateOptions(const std::string& path, const MeshImportOptions& options) {
  sim::RequirePositive(path + ": scale", options.scale, "m per file unit");
  const char* axis[] = {"x", "y", "z"};
  for (int c = 0; c < 3; ++c) {
    sim::RequireFinite(path + ": offset." + axis[c], options.offset[c], "m");
  }
}


const aiScene* ReadScene(Assimp::Importer& importer, const std::string& path) {
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, kDroppedComponents);
  const aiScene* scene = ReadAssimpScene(importer, path, kPostProcessSteps, "mesh file");
  if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) {
    throw InputError(path + ": cannot read the mesh file: assimp read it only partly");
  }
  if (scene->mNumMeshes == 0) throw InputError(path + ": the file holds no meshes");
  return scene;
}

std::string MeshLabel(const aiScene& scene, unsigned mesh) {
  return "mesh " + std::to_string(mesh) + " '" + scene.mMeshes[mesh]->mName.C_Str() + "'";
}

/// Refuses meshes that cannot be cloth before anything is collected.
void ValidateMeshes(const std::string& path, const aiScene& scene) {
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[m];
    if (mesh.mNumFaces == 0) {
      throw InputError(path + ": mesh has no faces (" + MeshLabel(scene, m) + ")");
    }
    if (!(mesh.mPrimitiveTypes & (aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON))) {
      throw InputError(path + ": mesh has no faces, only points or lines (" +
                       MeshLabel(scene, m) + "): a cloth needs triangles or quads");
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      if (mesh.mFaces[f].mNumIndices < 3) {
        throw InputError(path + ": " + MeshLabel(scene, m) + " face " + std::to_string(f) +
                         " has " + std::to_string(mesh.mFaces[f].mNumIndices) +
                         " vertices (a point or line): allowed 3 or more");
      }
    }
  }
}

Eigen::Matrix4d ToEigen(const aiMatrix4x4& m) {
  Eigen::Matrix4d result;
  result << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4, m.d1, m.d2,
      m.d3, m.d4;
  return result;
}

/// Gathers the faces of all meshes into one vertex list, joining equal positions.
class MeshCollector {
 public:
  MeshCollector(const std::string& path, const MeshImportOptions& options)
      : path_(path), options_(options) {}

  /// Adds `mesh` (named `label` in messages) placed by `node_to_file` (its node's global
  /// transform, in file units). Throws InputError for a vertex placed at no finite point.
  void AddMesh(const aiMesh& mesh, const std::string& label, const Eigen::Matrix4d& node_to_file) {
    const bool mirrored = node_to_file.topLeftCorner<3, 3>().determinant() < 0;
    std::vector<int> index(mesh.mNumVertices, -1);
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      std::vector<int> polygon;
      for (unsigned k = 0; k < face.mNumIndices; ++k) {
        const unsigned v = face.mIndices[k];
        if (index[v] < 0) index[v] = VertexIndex(Placed(mesh.mVertices[v], v, label, node_to_file));
        polygon.push_back(index[v]);
      }
      if (mirrored) std::reverse(polygon.begin(), polygon.end());
      AddPolygon(polygon);
    }
  }

  bool has_faces() const { return !faces_.empty(); }

  /// The collected mesh, named `source`.
  sim::SurfaceMesh TakeMesh(const std::string& source) {
    sim::SurfaceMesh mesh;
    mesh.source = source;
    mesh.vertices.resize(static_cast<Eigen::Index>(vertices_.size()), 3);
    for (std::size_t v = 0; v < vertices_.size(); ++v) {
      mesh.vertices.row(static_cast<Eigen::Index>(v)) = vertices_[v].transpose();
    }
    mesh.faces = std::move(faces_);
    return mesh;
  }

 private:
  /// Vertex `v` in the scene frame. ReadAssimpScene refused non-finite file coordinates;
  /// this catches a node transform or a scale that takes a finite one beyond a double.
  Eigen::Vector3d Placed(const aiVector3D& p, unsigned v, const std::string& label,
                         const Eigen::Matrix4d& node_to_file) const {
    const Eigen::Vector4d file = node_to_file * Eigen::Vector4d(p.x, p.y, p.z, 1.0);
    const Eigen::Vector3d placed = options_.scale * file.head<3>() + options_.offset;
    if (!placed.allFinite()) {
      throw InputError(path_ + ": " + label + " vertex " + std::to_string(v) + " at " +
                       sim::FormatValues({p.x, p.y, p.z}) +
                       " (file units) is not a finite point once placed and scaled"
                       " (allowed: finite coordinates)");
    }
    return placed;
  }

  int VertexIndex(const Eigen::Vector3d& p) {
    // + 0.0 turns -0 into +0 so that the two zeros join.
    const std::array<double, 3> key = {p.x() + 0.0, p.y() + 0.0, p.z() + 0.0};
    const auto [it, inserted] = index_of_.emplace(key, static_cast<int>(vertices_.size()));
    if (inserted) vertices_.push_back(p);
    return it->second;
  }

  /// Keeps triangles and quads; cuts larger polygons into a fan from their first vertex.
  void AddPolygon(const std::vector<int>& polygon) {
    if (polygon.size() <= 4) {
      faces_.push_back(polygon);
      return;
    }
    for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
      faces_.push_back({polygon[0], polygon[k], polygon[k + 1]});
    }
  }

  const std::string& path_;
  const MeshImportOptions& options_;
  std::map<std::array<double, 3>, int> index_of_;
  std::vector<Eigen::Vector3d> vertices_;
  std::vector<std::vector<int>> faces_;
};

/// Visits every node, adding its meshes under its global transform (parent · own).
void CollectNodes(const aiScene& scene, MeshCollector& collector) {
  std::vector<std::pair<const aiNode*, Eigen::Matrix4d>> pending = {
      {scene.mRootNode, ToEigen(scene.mRootNode->mTransformation)}};
  while (!pending.empty()) {
    const auto [node, node_to_file] = pending.back();
    pending.pop_back();
    for (unsigned m = 0; m < node->mNumMeshes; ++m) {
      collector.AddMesh(*scene.mMeshes[node->mMeshes[m]], MeshLabel(scene, node->mMeshes[m]),
                        node_to_file);
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c) {
      const aiNode* child = node->mChildren[c];
      pending.emplace_back(child, node_to_file * ToEigen(child->mTransformation));
    }
  }
}

}  // namespace

sim::SurfaceMesh ImportSurfaceMesh(const std::string& path, const MeshImportOptions& options) {
  ValidateOptions(path, options);
  Assimp::Importer importer;
  const aiScene* scene = ReadScene(importer, path);
  ValidateMeshes(path, *scene);
  MeshCollector collector(path, options);
  if (scene->mRootNode != nullptr) CollectNodes(*scene, collector);
  if (!collector.has_faces()) {
    throw InputError(path + ": mesh has no faces (no node of the scene uses a mesh)");
  }
  return collector.TakeMesh(path);
}

}  // namespace costume::assets
