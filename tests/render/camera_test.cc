#include "render/camera.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace costume::render {
namespace {

// A camera at (0, 0, 2) looking down -z with a 90° vertical field of view: at distance 2 the
// view spans y in [-2, 2] and, for aspect 2, x in [-4, 4]; so (1, 0.5, 0) lands at
// x = (1/4 + 1)/2 · W and y = (1 − 0.5/2)/2 · H (y down).
TEST(Camera, ProjectsLikeThePinholeModel) {
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 0, 2);
  camera.target = Eigen::Vector3d(0, 0, 0);
  camera.up = Eigen::Vector3d(0, 1, 0);
  camera.fov_y_degrees = 90;  // tan(45°) = 1: the view at distance 2 spans y in [-2, 2]
  const int width = 200, height = 100;  // aspect 2: x spans [-4, 4] at distance 2
  const auto p = ProjectToPixel(camera, Eigen::Vector3d(1, 0.5, 0), width, height);
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->x(), (1.0 / 4.0 + 1.0) / 2.0 * width, 1e-9);
  EXPECT_NEAR(p->y(), (1.0 - 0.5 / 2.0) / 2.0 * height, 1e-9);
  // The target is the image centre; a point behind the eye has no pixel.
  const auto centre = ProjectToPixel(camera, Eigen::Vector3d::Zero(), width, height);
  EXPECT_NEAR(centre->x(), 100, 1e-9);
  EXPECT_NEAR(centre->y(), 50, 1e-9);
  EXPECT_FALSE(ProjectToPixel(camera, Eigen::Vector3d(0, 0, 3), width, height).has_value());
  EXPECT_FALSE(ProjectToPixel(camera, Eigen::Vector3d(0, 0, -100), width, height).has_value());
}

TEST(Camera, PixelRayAndProjectToPixelAreInverse) {
  std::mt19937 random(4);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    Camera camera;
    camera.eye = Eigen::Vector3d(3 * unit(random), 1.5 + unit(random), 3 + unit(random));
    camera.target = Eigen::Vector3d(unit(random), 1 + unit(random), unit(random));
    camera.fov_y_degrees = 30 + 20 * (1 + unit(random));
    const int width = 320 + trial, height = 240;
    const double x = (0.5 + 0.45 * unit(random)) * width;
    const double y = (0.5 + 0.45 * unit(random)) * height;
    const Ray ray = PixelRay(camera, x, y, width, height);
    EXPECT_NEAR(ray.direction.norm(), 1.0, 1e-12);
    EXPECT_NEAR((ray.origin - camera.eye).norm(), 0.0, 1e-12);
    // Every point along the ray projects back onto (x, y).
    for (double distance : {0.5, 2.0, 7.0}) {
      const auto p = ProjectToPixel(camera, ray.origin + distance * ray.direction, width, height);
      ASSERT_TRUE(p.has_value());
      EXPECT_NEAR(p->x(), x, 1e-7);
      EXPECT_NEAR(p->y(), y, 1e-7);
    }
    // And the ray through a projected point passes through it.
    const Eigen::Vector3d point(unit(random), 1 + unit(random), unit(random));
    const auto q = ProjectToPixel(camera, point, width, height);
    ASSERT_TRUE(q.has_value());
    const Ray back = PixelRay(camera, q->x(), q->y(), width, height);
    const Eigen::Vector3d to_point = point - back.origin;
    EXPECT_NEAR((to_point - to_point.dot(back.direction) * back.direction).norm(), 0.0, 1e-9);
  }
}

TEST(Camera, FrameBoxKeepsEveryCornerInTheImage) {
  std::mt19937 random(9);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3d centre(unit(random), 1 + unit(random), unit(random));
    const Eigen::Vector3d half(0.05 + std::abs(unit(random)), 0.05 + std::abs(unit(random)),
                               0.05 + std::abs(unit(random)));
    const Eigen::AlignedBox3d box(centre - half, centre + half);
    Eigen::Vector3d direction(unit(random), unit(random), unit(random));
    if (trial == 0) direction = Eigen::Vector3d(0, -1, 0);  // straight down: up is -z
    if (direction.norm() < 0.1) continue;
    const double fov = 20 + 40 * (1 + unit(random));
    const Camera camera = FrameBox(box, direction, fov);
    EXPECT_NEAR((camera.target - centre).norm(), 0.0, 1e-12);
    EXPECT_GT((camera.target - camera.eye).normalized().dot(direction.normalized()), 1 - 1e-12);
    for (const auto& [width, height] : {std::pair{256, 256}, {640, 480}}) {
      // Inside the image, and framed rather than lost in the middle: the corner furthest from
      // the image's centre is near the border (the fit is made for the height; wider images
      // leave room at the sides).
      double furthest = 0.0;
      for (int i = 0; i < 8; ++i) {
        const auto p = ProjectToPixel(
            camera, box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(i)), width, height);
        ASSERT_TRUE(p.has_value()) << "corner " << i << " of trial " << trial;
        EXPECT_GE(p->x(), 0);
        EXPECT_LE(p->x(), width);
        EXPECT_GE(p->y(), 0);
        EXPECT_LE(p->y(), height);
        furthest = std::max({furthest, std::abs(p->x() - 0.5 * width) / (0.5 * height),
                             std::abs(p->y() - 0.5 * height) / (0.5 * height)});
      }
      EXPECT_GT(furthest, 0.75);  // wide fields of view keep the eye outside the box
    }
  }
}

TEST(Camera, OrbitKeepsTheDistanceAndTurnsAboutTheTarget) {
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 1, 3);
  camera.target = Eigen::Vector3d(0, 1, 0);
  Orbit(camera, M_PI / 2, 0);
  // A quarter turn about +y takes the eye from +z to +x.
  EXPECT_NEAR((camera.eye - Eigen::Vector3d(3, 1, 0)).norm(), 0.0, 1e-12);
  Orbit(camera, 0, -M_PI / 6);  // negative pitch raises the eye by 30°
  EXPECT_NEAR((camera.eye - camera.target).norm(), 3.0, 1e-12);
  EXPECT_NEAR(camera.eye.y() - 1, 3 * std::sin(M_PI / 6), 1e-12);
  Orbit(camera, 0, -10.0);  // far past the pole: stops short of it
  EXPECT_LT(camera.eye.y() - 1, 3.0);
  EXPECT_GT(camera.eye.y() - 1, 3 * std::sin(88.0 * M_PI / 180));
  EXPECT_NEAR((camera.eye - camera.target).norm(), 3.0, 1e-9);
}

TEST(Camera, PanMovesEyeAndTargetInTheViewPlane) {
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 1, 4);
  camera.target = Eigen::Vector3d(0, 1, 0);
  camera.fov_y_degrees = 90;  // view height at the target: 2 · 4 · tan(45°) = 8 m
  Pan(camera, 0.25, -0.5);
  EXPECT_NEAR((camera.target - Eigen::Vector3d(2, -3, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((camera.eye - Eigen::Vector3d(2, -3, 4)).norm(), 0.0, 1e-12);
}

TEST(Camera, ZoomDividesTheDistance) {
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 1, 4);
  camera.target = Eigen::Vector3d(0, 1, 0);
  Zoom(camera, 2.0);
  EXPECT_NEAR((camera.eye - Eigen::Vector3d(0, 1, 2)).norm(), 0.0, 1e-12);
  Zoom(camera, 0.0);  // ignored
  Zoom(camera, -1.0);
  EXPECT_NEAR((camera.eye - Eigen::Vector3d(0, 1, 2)).norm(), 0.0, 1e-12);
}

}  // namespace
}  // namespace costume::render
