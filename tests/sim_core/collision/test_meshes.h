#pragma once
// Closed test meshes with closed-form distances: a box tessellated into a grid on each
// face, and a sphere made by pushing such a cube's vertices onto the sphere.

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/cloth/cloth_model.h"

namespace costume::sim::test {

struct TestMesh {
  Points vertices;
  std::vector<Eigen::Vector3i> triangles;
};

// A box of half extents `half` around `center` [m], with `divisions[i]` grid cells along
// axis i on every face, counter-clockwise seen from outside, vertices welded.
inline TestMesh TessellatedBox(const Eigen::Vector3d& center, const Eigen::Vector3d& half,
                               const Eigen::Vector3i& divisions) {
  std::map<std::array<long long, 3>, int> index;
  std::vector<Eigen::Vector3d> positions;
  auto vertex = [&](const Eigen::Vector3d& x) {
    const std::array<long long, 3> key = {std::llround(x.x() * 1e9), std::llround(x.y() * 1e9),
                                          std::llround(x.z() * 1e9)};
    const auto [it, added] = index.emplace(key, static_cast<int>(positions.size()));
    if (added) positions.push_back(x);
    return it->second;
  };
  TestMesh mesh;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {1, -1}) {
      int j = (axis + 1) % 3, k = (axis + 2) % 3;
      if (sign < 0) std::swap(j, k);  // keeps j × k pointing out of the face
      const int na = divisions[j], nb = divisions[k];
      auto at = [&](int a, int b) {
        Eigen::Vector3d x;
        x[axis] = sign * half[axis];
        x[j] = -half[j] + 2.0 * half[j] * a / na;
        x[k] = -half[k] + 2.0 * half[k] * b / nb;
        return vertex(center + x);
      };
      for (int a = 0; a < na; ++a) {
        for (int b = 0; b < nb; ++b) {
          const int v00 = at(a, b), v10 = at(a + 1, b), v11 = at(a + 1, b + 1), v01 = at(a, b + 1);
          mesh.triangles.emplace_back(v00, v10, v11);
          mesh.triangles.emplace_back(v00, v11, v01);
        }
      }
    }
  }
  mesh.vertices.resize(static_cast<Eigen::Index>(positions.size()), 3);
  for (std::size_t v = 0; v < positions.size(); ++v) mesh.vertices.row(v) = positions[v];
  return mesh;
}

// A sphere of `radius` around `center` [m]: a cube with `divisions` cells per face edge,
// its vertices pushed onto the sphere (so the mesh lies inside it).
inline TestMesh CubeSphere(const Eigen::Vector3d& center, double radius, int divisions) {
  TestMesh mesh = TessellatedBox(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones(),
                                 Eigen::Vector3i::Constant(divisions));
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    mesh.vertices.row(v) = center.transpose() + radius * mesh.vertices.row(v).normalized();
  }
  return mesh;
}

// Exact signed distance to the box (negative inside) [m].
inline double BoxSignedDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& center,
                                const Eigen::Vector3d& half) {
  const Eigen::Vector3d q = (p - center).cwiseAbs() - half;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

// The mesh with every vertex moved by `offset` [m].
inline TestMesh Translated(TestMesh mesh, const Eigen::Vector3d& offset) {
  mesh.vertices.rowwise() += offset.transpose();
  return mesh;
}

/// An avatar whose only joint carries every vertex of `mesh`.
inline std::shared_ptr<const Avatar> RigidAvatar(const TestMesh& mesh) {
  Joint root;
  root.name = "root";
  AvatarData data;
  data.name = "test body";
  data.skeleton = Skeleton::Create("one joint", {root});
  data.rest_vertices = mesh.vertices;
  data.triangles = mesh.triangles;
  const Eigen::Index n = mesh.vertices.rows();
  data.influence_joints.setConstant(n, kMaxInfluences, -1);
  data.influence_joints.col(0).setZero();
  data.influence_weights.setZero(n, kMaxInfluences);
  data.influence_weights.col(0).setOnes();
  return Avatar::Create(std::move(data));
}

}  // namespace costume::sim::test
