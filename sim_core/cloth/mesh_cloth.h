#pragma once
/// @file
/// Cloth models from general polygon meshes (triangles and quads), e.g. garments read from
/// files by the assets layer. The rule for structural, shear and bending springs on a
/// general mesh is documented in docs/cloth_model.md and in BuildMeshCloth below.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/material.h"

namespace costume::sim {

/// A polygon mesh as read from a file: vertices and faces of 3 or 4 vertex indices.
struct SurfaceMesh {
  /// Vertex positions (n×3) [m], already in the scene frame.
  Points vertices;
  /// Faces, each a list of 3 or 4 vertex indices, counter-clockwise from the front.
  std::vector<std::vector<int>> faces;
  /// Where the mesh came from (file path), quoted in error messages.
  std::string source;
};

/// Builds model data from a mesh (see the header comment of the .cc and
/// docs/cloth_model.md for the spring rule and how stiffnesses scale with element size).
/// In short: face sides are structural springs; quad diagonals and the far vertices of
/// two triangles sharing an edge are shear springs; bending springs skip one vertex along
/// roughly straight lines (on a square quad grid exactly the lattice's). Masses are lumped
/// (density · ⅓ of each adjacent triangle's area, quads split along the shorter diagonal),
/// `triangles` holds every triangle, pins are left to the caller, lattice_rows/cols are 0.
/// Throws InputError naming `name` / mesh.source for: a bad material, no vertices, no faces,
/// a face with other than 3 or 4 vertices, an index out of range or repeated in a face,
/// degenerate (area < 1e-14 m²) faces, coincident vertices joined by an edge, non-finite
/// coordinates, or a vertex that belongs to no face.
ClothModelData BuildMeshCloth(const SurfaceMesh& mesh, const Material& material,
                              const std::string& name);

/// Joins the ends of every edge shorter than `min_length` [m] (transitively) into one vertex
/// at their mean position, and drops the faces that collapse (fewer than 3 distinct vertices;
/// a quad that loses one becomes a triangle). Millimetre edges (a rolled hem modelled as a
/// strip) would make particles of micrograms held by stiff bending springs: h²k/m beyond any
/// step a frame can afford. Vertices in no face afterwards are removed. Throws InputError
/// naming mesh.source when min_length is negative or not finite.
SurfaceMesh WeldShortEdges(const SurfaceMesh& mesh, double min_length);

}  // namespace costume::sim
