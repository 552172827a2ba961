// Pseudonormals of a triangle mesh: the angle-weighted vertex normal against a box corner's
// closed form, and the on-demand vertex normals (Update without them, or none) against the
// eager ones.
#include "sim_core/collision/surface_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/sim_core/collision/test_meshes.h"

namespace costume::sim {
namespace {

TEST(SurfacePseudonormals, BoxCornerNormalIsTheDiagonal) {
  // Each of the three faces meets a corner at a right angle, however they are split into
  // triangles, so the angle-weighted normal is the normalised sum of the face normals.
  const test::TestMesh box = test::TessellatedBox(Eigen::Vector3d::Zero(),
                                                  Eigen::Vector3d(0.3, 0.2, 0.1),
                                                  Eigen::Vector3i(3, 4, 5));
  SurfacePseudonormals normals(static_cast<int>(box.vertices.rows()), box.triangles);
  normals.Update(box.vertices);
  int corners = 0;
  for (Eigen::Index v = 0; v < box.vertices.rows(); ++v) {
    const Eigen::Vector3d x = box.vertices.row(v).transpose();
    if (std::abs(std::abs(x.x()) - 0.3) > 1e-12 || std::abs(std::abs(x.y()) - 0.2) > 1e-12 ||
        std::abs(std::abs(x.z()) - 0.1) > 1e-12) {
      continue;
    }
    ++corners;
    const Eigen::Vector3d want = x.cwiseSign() / std::sqrt(3.0);
    EXPECT_LT((normals.VertexNormal(static_cast<int>(v), box.vertices) - want).norm(), 1e-12);
  }
  EXPECT_EQ(corners, 8);
}

TEST(SurfacePseudonormals, VertexNormalsOnDemandAreThoseOfUpdateBitForBit) {
  test::TestMesh sphere = test::CubeSphere(Eigen::Vector3d(0.1, 1.0, -0.2), 0.3, 6);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  for (Eigen::Index v = 0; v < sphere.vertices.rows(); ++v) {
    sphere.vertices.row(v) += Eigen::RowVector3d(jitter(rng), jitter(rng), jitter(rng));
  }
  const int n = static_cast<int>(sphere.vertices.rows());
  SurfacePseudonormals eager(n, sphere.triangles), lazy(n, sphere.triangles);
  eager.Update(sphere.vertices);
  lazy.Update(sphere.vertices, /*vertex_normals=*/false);
  for (int t = 0; t < eager.num_triangles(); ++t) {
    EXPECT_EQ(eager.face_normal(t), lazy.face_normal(t));
    for (TriangleFeature f : {TriangleFeature::kVertexA, TriangleFeature::kVertexB,
                              TriangleFeature::kVertexC, TriangleFeature::kEdgeAB,
                              TriangleFeature::kFace}) {
      EXPECT_EQ(eager.Of(t, f), lazy.Of(t, f, sphere.vertices)) << t;
    }
  }
  // From the vertices alone, never updated, and after a move that Update has not seen:
  // still Update's bits for the vertices given.
  const SurfacePseudonormals never_updated(n, sphere.triangles);
  for (int v = 0; v < n; ++v) {
    EXPECT_EQ(eager.VertexNormal(v, sphere.vertices),
              never_updated.VertexNormalOf(v, sphere.vertices)) << v;
  }
  Points moved = sphere.vertices;
  moved.col(0) *= 1.5;
  // Triangle 0 made degenerate: it adds nothing to its corners' normals.
  const Eigen::Vector3i& flat = sphere.triangles[0];
  moved.row(flat[0]) = moved.row(flat[1]);
  eager.Update(moved);
  ASSERT_EQ(eager.double_area(0), 0.0);
  for (int v = 0; v < n; ++v) {
    EXPECT_EQ(eager.VertexNormal(v, moved), lazy.VertexNormalOf(v, moved)) << v;
  }
}

}  // namespace
}  // namespace costume::sim
