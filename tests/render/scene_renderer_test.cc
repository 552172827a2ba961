#include "render/scene_renderer.h"

#include <gtest/gtest.h>

#include <cstring>

#include "render/offscreen_context.h"
#include "sim_core/common/input_error.h"
#include "tests/render/coverage.h"

namespace costume::render {
namespace {

using testing::DiffersFrom;
using testing::Rasterise;

constexpr int kWidth = 160, kHeight = 120;

Camera ObliqueCamera() {
  Camera camera;
  camera.eye = Eigen::Vector3d(0.3, 0.2, 2.0);
  camera.target = Eigen::Vector3d(0.0, 0.0, 0.0);
  camera.fov_y_degrees = 40;
  return camera;
}

RenderScene Plain() {
  RenderScene scene;
  scene.floor = false;
  return scene;
}

DrawMesh Triangle() {
  DrawMesh mesh;
  mesh.positions = {{-0.6f, -0.4f, 0.0f}, {0.5f, -0.3f, 0.2f}, {0.1f, 0.5f, -0.1f}};
  mesh.indices = {0, 1, 2};
  return mesh;
}

// A quad facing -z (clockwise seen from +z), drawn from a camera on +z: its back face.
DrawMesh BackFacingQuad(bool two_sided) {
  DrawMesh mesh;
  mesh.positions = {{-0.5f, -0.5f, 0.0f}, {0.5f, -0.5f, 0.0f}, {0.5f, 0.5f, 0.0f},
                    {-0.5f, 0.5f, 0.0f}};
  mesh.indices = {0, 2, 1, 0, 3, 2};
  mesh.colour = Eigen::Vector3f(0.2f, 0.8f, 0.4f);
  mesh.two_sided = two_sided;
  return mesh;
}

Image Render(OffscreenContext& context, SceneRenderer& renderer, const RenderScene& scene,
             const Camera& camera) {
  renderer.Draw(scene, camera, context.width(), context.height());
  return context.ReadPixels();
}

// Counts pixels where the rendered image disagrees with the CPU coverage, away from the
// silhouette (a pixel and its 8 neighbours all inside, or all outside).
struct Agreement {
  int inside = 0, outside = 0, wrong = 0;
};
Agreement Compare(const Image& image, const testing::CoverageMask& mask,
                  const Eigen::Vector3f& background) {
  Agreement result;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (mask.All(x, y, 1, true)) {
        ++result.inside;
        if (!DiffersFrom(image, x, y, background)) ++result.wrong;
      } else if (mask.All(x, y, 1, false)) {
        ++result.outside;
        if (DiffersFrom(image, x, y, background)) ++result.wrong;
      }
    }
  }
  return result;
}

TEST(SceneRenderer, TriangleCoversThePixelsItsProjectedCornersEnclose) {
  OffscreenContext context(kWidth, kHeight);
  SceneRenderer renderer(context.Loader());
  RenderScene scene = Plain();
  scene.meshes.push_back(Triangle());
  const Camera camera = ObliqueCamera();
  const Image image = Render(context, renderer, scene, camera);
  const Agreement agreement = Compare(image, Rasterise(scene.meshes, camera, kWidth, kHeight),
                                      scene.background);
  EXPECT_GT(agreement.inside, 2000);
  EXPECT_GT(agreement.outside, 5000);
  EXPECT_EQ(agreement.wrong, 0);
}

TEST(SceneRenderer, ImageRowsAreTopFirst) {
  // A triangle wholly in the upper half of the view shows in the image's first rows.
  OffscreenContext context(kWidth, kHeight);
  SceneRenderer renderer(context.Loader());
  RenderScene scene = Plain();
  DrawMesh mesh = Triangle();
  for (Eigen::Vector3f& p : mesh.positions) p = 0.3f * p + Eigen::Vector3f(0, 0.3f, 0);
  scene.meshes.push_back(mesh);
  const Camera camera = ObliqueCamera();
  const Image image = Render(context, renderer, scene, camera);
  int top = 0, bottom = 0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      if (DiffersFrom(image, x, y, scene.background)) ++(y < kHeight / 2 ? top : bottom);
    }
  }
  EXPECT_GT(top, 100);
  EXPECT_EQ(bottom, 0);
}

TEST(SceneRenderer, TwoSidedMeshesLightTheirBackFaces) {
  OffscreenContext context(kWidth, kHeight);
  SceneRenderer renderer(context.Loader());
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 0, 2);
  camera.target = Eigen::Vector3d::Zero();
  RenderScene scene = Plain();
  scene.meshes = {BackFacingQuad(false)};
  const Image one_sided = Render(context, renderer, scene, camera);
  scene.meshes = {BackFacingQuad(true)};
  const Image two_sided = Render(context, renderer, scene, camera);
  const int x = kWidth / 2, y = kHeight / 2;
  // One-sided, the back face sees neither light (the key light is on +z too): ambient only,
  // 0.22 of the colour.
  EXPECT_NEAR(one_sided.Pixel(x, y)[1], 0.22 * 0.8 * 255, 3);
  EXPECT_GT(two_sided.Pixel(x, y)[1], one_sided.Pixel(x, y)[1] + 100);
}

TEST(SceneRenderer, ReusedBuffersDrawLikeFreshOnes) {
  // Draw a large mesh, then a small one, then the large one again (its buffers now
  // overwritten in place): the last image equals a fresh renderer's.
  OffscreenContext context(kWidth, kHeight);
  const Camera camera = ObliqueCamera();
  RenderScene large = Plain();
  DrawMesh grid;
  const int n = 40;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      grid.positions.emplace_back(-0.6f + 1.2f * i / n, -0.5f + 1.0f * j / n,
                                  0.1f * std::sin(0.4f * i) * std::cos(0.3f * j));
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const std::uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      grid.indices.insert(grid.indices.end(), {a, b, d, a, d, c});
    }
  }
  large.meshes = {grid, Triangle()};
  RenderScene small = Plain();
  small.meshes = {Triangle()};
  Image reused;
  {
    SceneRenderer renderer(context.Loader());
    Render(context, renderer, large, camera);
    Render(context, renderer, small, camera);
    reused = Render(context, renderer, large, camera);
  }
  SceneRenderer fresh(context.Loader());
  const Image expected = Render(context, fresh, large, camera);
  EXPECT_EQ(reused.rgba, expected.rgba);
}

TEST(SceneRenderer, SelectionSphereIsTranslucent) {
  OffscreenContext context(kWidth, kHeight);
  SceneRenderer renderer(context.Loader());
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 0, 2);
  camera.target = Eigen::Vector3d::Zero();
  RenderScene scene = Plain();
  scene.selection = DrawSphere{Eigen::Vector3d(0, 0, 0.3), 0.2, {1.0f, 0.0f, 0.0f, 0.4f}};
  const int x = kWidth / 2, y = kHeight / 2;
  const Image sphere_only = Render(context, renderer, scene, camera);
  // Over the background: red raised, green and blue lowered, none replaced outright.
  const std::uint8_t* p = sphere_only.Pixel(x, y);
  EXPECT_GT(p[0], 200);
  EXPECT_LT(p[1], 0.93 * 255 - 40);
  EXPECT_GT(p[1], 60);
  EXPECT_EQ(p[3], 255);  // the image stays opaque
  // A mesh behind the sphere shows through it.
  scene.meshes = {BackFacingQuad(true)};
  const Image behind = Render(context, renderer, scene, camera);
  scene.selection.reset();
  const Image mesh_only = Render(context, renderer, scene, camera);
  EXPECT_NE(std::memcmp(behind.Pixel(x, y), sphere_only.Pixel(x, y), 3), 0);
  EXPECT_NE(std::memcmp(behind.Pixel(x, y), mesh_only.Pixel(x, y), 3), 0);
  EXPECT_GT(behind.Pixel(x, y)[1], 60);  // the quad's green still there
}

TEST(SceneRenderer, DrawsConeAndHandCursors) {
  OffscreenContext context(kWidth, kHeight);
  SceneRenderer renderer(context.Loader());
  Camera camera;
  camera.eye = Eigen::Vector3d(1, 0.3, 0);  // from the side
  camera.target = Eigen::Vector3d::Zero();
  camera.fov_y_degrees = 20;
  RenderScene scene = Plain();
  for (CursorShape shape : {CursorShape::kCone, CursorShape::kHand}) {
    scene.cursor = DrawCursor{Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity(), shape, 0.2};
    const Image image = Render(context, renderer, scene, camera);
    // The cone runs from its tip at the origin back along +z; the hand's fingers along -z
    // from its palm at the origin. A point inside each is drawn in the cursor's red.
    const Eigen::Vector3d inside =
        shape == CursorShape::kCone ? Eigen::Vector3d(0, 0, 0.14) : Eigen::Vector3d(0, 0, -0.02);
    const Eigen::Vector2d pixel = ProjectToPixel(camera, inside, kWidth, kHeight).value();
    const std::uint8_t* p = image.Pixel(static_cast<int>(pixel.x()), static_cast<int>(pixel.y()));
    EXPECT_GT(p[0], p[1] + 60) << "shape " << static_cast<int>(shape);
    // And nothing is drawn far from it.
    const Eigen::Vector2d away =
        ProjectToPixel(camera, Eigen::Vector3d(0, 0.12, 0), kWidth, kHeight).value();
    ASSERT_GT(away.y(), 0.0);
    EXPECT_FALSE(DiffersFrom(image, static_cast<int>(away.x()), static_cast<int>(away.y()),
                             scene.background));
  }
}

TEST(SceneRenderer, FloorIsDrawnUnderTheScene) {
  OffscreenContext context(kWidth, kHeight);
  SceneRenderer renderer(context.Loader());
  // Looking level from 0.5 m up: the floor below the horizon (the image's lower half),
  // the background above it.
  Camera camera;
  camera.eye = Eigen::Vector3d(0, 0.5, 3);
  camera.target = Eigen::Vector3d(0, 0.5, 0);
  RenderScene scene;
  const Image image = Render(context, renderer, scene, camera);
  EXPECT_TRUE(DiffersFrom(image, kWidth / 2, kHeight - 2, scene.background));
  EXPECT_FALSE(DiffersFrom(image, kWidth / 2, 2, scene.background));
  scene.floor = false;
  const Image without = Render(context, renderer, scene, camera);
  EXPECT_FALSE(DiffersFrom(without, kWidth / 2, kHeight - 2, scene.background));
  // Raised above the eye, the floor no longer shows below the horizon.
  scene.floor = true;
  scene.floor_height = 1.0f;
  const Image raised = Render(context, renderer, scene, camera);
  EXPECT_FALSE(DiffersFrom(raised, kWidth / 2, kHeight - 2, scene.background));
}

// A loader for a context that claims an old OpenGL.
void* OldGlLoader(const char* name) {
  static const GLubyte* (*get_string)(GLenum) = [](GLenum) -> const GLubyte* {
    return reinterpret_cast<const GLubyte*>("2.1 Mesa 22.3.6");
  };
  return std::strcmp(name, "glGetString") == 0 ? reinterpret_cast<void*>(get_string) : nullptr;
}

TEST(SceneRenderer, RefusesContextsOlderThan33NamingTheVersion) {
  try {
    SceneRenderer renderer(OldGlLoader);
    FAIL() << "an OpenGL 2.1 context was accepted";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("2.1 Mesa 22.3.6"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("3.3"), std::string::npos) << error.what();
  }
  EXPECT_THROW(SceneRenderer([](const char*) -> void* { return nullptr; }), sim::InputError);
}

TEST(OffscreenContext, GivesAnOpenGl33CoreContext) {
  OffscreenContext context(32, 16);
  SceneRenderer renderer(context.Loader());
  int major = 0, minor = 0;
  ASSERT_EQ(std::sscanf(renderer.GlVersion(), "%d.%d", &major, &minor), 2) << renderer.GlVersion();
  EXPECT_TRUE(major > 3 || (major == 3 && minor >= 3)) << renderer.GlVersion();
  const Image image = context.ReadPixels();
  EXPECT_EQ(image.width, 32);
  EXPECT_EQ(image.height, 16);
  EXPECT_EQ(image.rgba.size(), 32u * 16u * 4u);
  EXPECT_THROW(OffscreenContext(0, 10), sim::InputError);
  EXPECT_THROW(OffscreenContext(10, 100000), sim::InputError);
}

}  // namespace
}  // namespace costume::render
