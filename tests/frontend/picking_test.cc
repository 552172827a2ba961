#include "frontend/picking.h"

#include <gtest/gtest.h>

#include "render/camera.h"

namespace costume::frontend {
namespace {

/// A unit square in the plane z = 0, two triangles, and a second square at z = -1 behind it.
struct TwoSquares {
  std::vector<Eigen::Vector3f> positions = {{0, 0, 0},  {1, 0, 0},  {1, 1, 0},  {0, 1, 0},
                                            {0, 0, -1}, {1, 0, -1}, {1, 1, -1}, {0, 1, -1}};
  std::vector<std::uint32_t> indices = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
};

TEST(PickTriangles, FindsTheNearestHitFromEitherSide) {
  TwoSquares s;
  const Eigen::Vector3d down(0, 0, -1);
  const auto front = PickTriangles({0.25, 0.75, 2.0}, down, s.positions, s.indices);
  ASSERT_TRUE(front);
  EXPECT_NEAR(front->distance, 2.0, 1e-12);
  EXPECT_TRUE(front->point.isApprox(Eigen::Vector3d(0.25, 0.75, 0.0)));
  EXPECT_EQ(front->triangle, 1);  // (0,0)-(1,1)-(0,1) holds x < y
  const auto back = PickTriangles({0.75, 0.25, -3.0}, -down, s.positions, s.indices);
  ASSERT_TRUE(back);
  EXPECT_NEAR(back->distance, 2.0, 1e-12);
  EXPECT_EQ(back->triangle, 2);
}

TEST(PickTriangles, MissesBesideAndBehind) {
  TwoSquares s;
  EXPECT_FALSE(PickTriangles({1.5, 0.5, 2.0}, {0, 0, -1}, s.positions, s.indices));
  EXPECT_FALSE(PickTriangles({0.5, 0.5, 2.0}, {0, 0, 1}, s.positions, s.indices));
  std::vector<std::uint32_t> bad = {0, 1, 99};
  EXPECT_FALSE(PickTriangles({0.5, 0.2, 2.0}, {0, 0, -1}, s.positions, bad));
}

TEST(PickTriangles, ThePixelUnderAProjectedPointPicksThatPoint) {
  TwoSquares s;
  render::Camera camera;
  camera.eye = {0.3, 0.6, 3.0};
  camera.target = {0.5, 0.5, 0.0};
  const Eigen::Vector3d point(0.4, 0.7, 0.0);
  const auto pixel = render::ProjectToPixel(camera, point, 640, 480);
  ASSERT_TRUE(pixel);
  const render::Ray ray = render::PixelRay(camera, pixel->x(), pixel->y(), 640, 480);
  const auto hit = PickTriangles(ray.origin, ray.direction, s.positions, s.indices);
  ASSERT_TRUE(hit);
  EXPECT_LT((hit->point - point).norm(), 1e-6);
}

TEST(RayPlane, KeepsTheGrabbedPointUnderThePointer) {
  // Plane through (0, 1, 0) facing +z; rays from (0, 1, 5).
  const auto p = RayPlane({0, 1, 5}, Eigen::Vector3d(0.6, 0, -0.8), {0, 1, 0}, {0, 0, 1});
  ASSERT_TRUE(p);
  EXPECT_TRUE(p->isApprox(Eigen::Vector3d(3.75, 1, 0)));  // 5 / 0.8 along the ray
  EXPECT_FALSE(RayPlane({0, 1, 5}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}));   // parallel
  EXPECT_FALSE(RayPlane({0, 1, 5}, {0, 0, 1}, {0, 1, 0}, {0, 0, 1}));   // behind
}

}  // namespace
}  // namespace costume::frontend
