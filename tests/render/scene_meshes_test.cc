#include "render/scene_meshes.h"

#include <gtest/gtest.h>

namespace costume::render {
namespace {

TEST(SceneMeshes, ToDrawMeshKeepsPositionsAndTriangles) {
  sim::Points points(4, 3);
  points << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0.5;
  const std::vector<Eigen::Vector3i> triangles = {{0, 1, 2}, {0, 2, 3}};
  const DrawMesh mesh = ToDrawMesh(points, triangles, kClothColour, true);
  ASSERT_EQ(mesh.positions.size(), 4u);
  EXPECT_EQ(mesh.positions[3], Eigen::Vector3f(0, 1, 0.5f));
  EXPECT_EQ(mesh.indices, (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(mesh.colour, kClothColour);
  EXPECT_TRUE(mesh.two_sided);
}

TEST(SceneMeshes, UpdatePositionsKeepsTrianglesAndStorage) {
  sim::Points points = sim::Points::Zero(3, 3);
  DrawMesh mesh = ToDrawMesh(points, {{0, 1, 2}}, kSkinColour, false);
  const Eigen::Vector3f* storage = mesh.positions.data();
  points(2, 1) = 2.5;
  UpdatePositions(mesh, points);
  EXPECT_EQ(mesh.positions[2], Eigen::Vector3f(0, 2.5f, 0));
  EXPECT_EQ(mesh.positions.data(), storage);
  EXPECT_EQ(mesh.indices.size(), 3u);
}

}  // namespace
}  // namespace costume::render
