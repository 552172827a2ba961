#pragma once
/// @file
/// The one OpenGL 3.3 core renderer of the project: the avatar, the cloth with lighting, the
/// transparent selection sphere and the device cursor. Used offscreen (OSMesa thumbnails) and by
/// the Qt GUI's QOpenGLWidget; it needs only a current GL 3.3 core context and a GlLoader.

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "render/camera.h"
#include "render/gl_functions.h"

namespace costume::render {

/// A triangle mesh to draw: world positions [m], triangles as index triples into positions.
/// Normals are computed per vertex from the triangles (area-weighted, smooth shading).
struct DrawMesh {
  std::vector<Eigen::Vector3f> positions;  ///< world positions [m]
  std::vector<std::uint32_t> indices;      ///< triangles, 3 indices each, counter-clockwise front
  Eigen::Vector3f colour{0.8f, 0.8f, 0.8f};  ///< diffuse colour, linear RGB in [0, 1]
  bool two_sided = false;  ///< light the back faces too (cloth), with the flipped normal
};

/// The transparent selection sphere of the editing mode.
struct DrawSphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< [m]
  double radius = 0.1;                               ///< [m]
  Eigen::Vector4f colour{1, 0.8f, 0.2f, 0.35f};      ///< RGB and opacity in [0, 1]
};

/// The shape of the device cursor: a cone for a stylus (haptic arm, mouse), a hand for a glove.
enum class CursorShape { kCone, kHand };

/// The device cursor. The cone's tip is at `position` and it points along the orientation's -z
/// axis (the stylus direction); the hand's palm centre is at `position`, fingers along -z,
/// palm facing -y of the orientation.
struct DrawCursor {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();                 ///< [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();     ///< world from cursor
  CursorShape shape = CursorShape::kCone;
  double size = 0.05;  ///< overall length [m]
};

/// Everything one frame shows.
struct RenderScene {
  std::vector<DrawMesh> meshes;             ///< avatar, cloth, ... (opaque)
  std::optional<DrawSphere> selection;      ///< drawn last, blended
  std::optional<DrawCursor> cursor;         ///< the device cursor
  Eigen::Vector3f background{0.93f, 0.93f, 0.95f};  ///< clear colour, RGB in [0, 1]
  bool floor = true;  ///< a floor grid at y = floor_height (under the scene's footprint)
  float floor_height = 0.0f;  ///< [m]: where the avatar's feet are (MakeHuman's are at −0.8 m)
};

/// Draws a RenderScene into the current framebuffer. Holds GL objects (program, vertex arrays,
/// buffers) created in the context current at construction; use it only with that context
/// current, and destroy it while that context is still current. Buffers are reused between
/// frames and grow only when a mesh grows, so redrawing at 60 Hz allocates little.
class SceneRenderer {
 public:
  /// Loads the GL functions through `loader` and builds the shaders. Needs a current OpenGL
  /// 3.3 core context; throws sim::InputError naming the context's GL version when it is older,
  /// or a shader's log when compilation fails.
  explicit SceneRenderer(const GlLoader& loader);
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  /// Draws `scene` as seen by `camera` into the current framebuffer's viewport of
  /// width × height pixels (> 0). Clears colour and depth first.
  void Draw(const RenderScene& scene, const Camera& camera, int width, int height);

  /// The GL_VERSION string of the context the renderer was built in.
  const char* GlVersion() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace costume::render
