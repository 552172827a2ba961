#pragma once
/// @file
/// Reading garment meshes (OBJ, glTF, FBX, Collada, ... anything assimp reads) into the
/// sim::SurfaceMesh that sim::BuildMeshCloth turns into a cloth.

#include <Eigen/Core>
#include <string>

#include "sim_core/cloth/mesh_cloth.h"

namespace costume::assets {

/// How file coordinates become scene coordinates: p_scene = scale · p_file + offset, where
/// p_file already includes the file's own node transforms.
struct MeshImportOptions {
  /// Metres per file unit, finite and > 0. MakeHuman's OBJ files are in decimetres: 0.1.
  double scale = 1.0;
  /// Added after scaling [m], finite.
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};

/// Reads the mesh file at `path` with assimp and returns one SurfaceMesh (source = `path`)
/// holding every mesh of the file's scene, each placed by its node's global transform
/// (a mesh used by two nodes appears twice).
/// - Vertices at exactly the same position are joined, within and across the file's meshes,
///   so that UV seams and the groups of an OBJ make one connected cloth (assimp's
///   JoinIdenticalVertices alone keeps vertices that differ in texture coordinates apart).
///   Two vertices a designer meant to keep apart but placed at the same point are joined too.
/// - Triangles and quads are kept as they are (the quads become shear diagonals, see
///   mesh_cloth.h); polygons of 5 or more vertices are cut into a fan of triangles from their
///   first vertex, which is right for convex polygons (the usual case for exported meshes).
/// - Under a mirroring node transform (negative determinant) faces are reversed, so that they
///   stay counter-clockwise seen from the front.
/// Throws sim::InputError naming `path` for: scale not finite and > 0 (field "scale"), a
/// non-finite offset, a file that does not exist or cannot be read, a file assimp refuses
/// (quoting assimp's error), a scene with no meshes, a mesh with no faces or only points and
/// lines, a face of fewer than 3 vertices, a vertex at no finite point (a "nan" or a number
/// beyond a float's range). The mesh is not otherwise checked here:
/// sim::BuildMeshCloth refuses degenerate faces and vertices in no face.
sim::SurfaceMesh ImportSurfaceMesh(const std::string& path, const MeshImportOptions& options);

}  // namespace costume::assets
