#include "render/scene_meshes.h"

namespace costume::render {

DrawMesh ToDrawMesh(const sim::Points& positions, const std::vector<Eigen::Vector3i>& triangles,
                    const Eigen::Vector3f& colour, bool two_sided) {
  DrawMesh mesh;
  UpdatePositions(mesh, positions);
  mesh.indices.reserve(3 * triangles.size());
  for (const Eigen::Vector3i& t : triangles) {
    mesh.indices.insert(mesh.indices.end(), {static_cast<std::uint32_t>(t[0]),
                                             static_cast<std::uint32_t>(t[1]),
                                             static_cast<std::uint32_t>(t[2])});
  }
  mesh.colour = colour;
  mesh.two_sided = two_sided;
  return mesh;
}

void UpdatePositions(DrawMesh& mesh, const sim::Points& positions) {
  mesh.positions.resize(positions.rows());
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    mesh.positions[i] = positions.row(i).transpose().cast<float>();
  }
}

}  // namespace costume::render
