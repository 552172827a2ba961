#pragma once
/// @file
/// The 3D view: a QOpenGLWidget (OpenGL 3.3 core) drawing through render::SceneRenderer, the
/// renderer of the thumbnails, with the context's getProcAddress as the loader. Shows the
/// avatar and the lit cloth of the latest frame (triangles from the SceneMirror), the
/// selection sphere and the device cursor. Left drag on empty space orbits, middle drag or
/// shift + left drag pans, the wheel zooms. Left press on the cloth grabs it with the mouse:
/// the view emits pointer samples (pointerSample) which the window sends on COSTUME_POINTER
/// for the haptic server's mouse device.

// The renderer's GL declarations (glcorearb.h) must come before Qt's (qopengl.h includes
// GL/gl.h, after which glcorearb.h would skip the GL 1.x function-pointer types).
#include "render/camera.h"
#include "render/scene_renderer.h"

#include <QOpenGLWidget>
#include <memory>
#include <optional>
#include <vector>

#include "frontend/cloth_frame_assembler.h"
#include "frontend/scene_mirror.h"

namespace costume::frontend {

/// Colours of the view (linear RGB in [0, 1]); the screenshot test reads them back.
struct ViewColours {
  Eigen::Vector3f avatar{0.80f, 0.55f, 0.42f};
  Eigen::Vector3f cloth{0.15f, 0.30f, 0.85f};
  Eigen::Vector3f background{0.93f, 0.93f, 0.95f};
};

/// The mouse's state as a pointing device.
enum class PointerGesture { kNone, kOrbit, kPan, kGrab };

class ViewWidget : public QOpenGLWidget {
  Q_OBJECT

 public:
  explicit ViewWidget(QWidget* parent = nullptr);
  ~ViewWidget() override;

  /// The scene to draw (not owned; may be null). Frames the camera on it.
  void SetMirror(const SceneMirror* mirror);
  /// The latest whole cloth frame (positions) to draw.
  void SetFrame(const ClothFrame& frame);
  /// The device cursor: position [m], orientation (world from cursor), glove (hand) or
  /// stylus (cone). Hidden with HideCursor.
  void SetCursor(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                 bool glove);
  void HideCursor();
  /// Selection radius shown around the cursor or the mouse grab [m].
  void SetSelectionRadius(double radius) { radius_ = radius; update(); }
  /// Shows the selection sphere (editing mode).
  void SetSelectionVisible(bool visible) { selection_visible_ = visible; update(); }

  render::Camera& camera() { return camera_; }
  const render::Camera& camera() const { return camera_; }
  /// The cloth positions drawn (the last frame's, or the mirror's rest positions).
  const std::vector<Eigen::Vector3f>& cloth_positions() const { return cloth_; }
  /// Where a mouse grab holds the cloth now [m]; empty when not grabbing.
  std::optional<Eigen::Vector3d> grab_point() const;
  /// The renderer's GL_VERSION, or the error that kept it from starting ("" before init).
  const QString& gl_info() const { return gl_info_; }
  /// The scene as it would be drawn now (for offscreen export and tests).
  render::RenderScene BuildScene() const;

 signals:
  /// A pointer sample for the mouse device: position [m], buttons (bit 0 grab), inside.
  void pointerSample(const Eigen::Vector3d& position, int buttons, bool inside_view);
  /// A mouse grab started at `point` [m] on the cloth.
  void grabStarted(const Eigen::Vector3d& point);
  void grabEnded(const Eigen::Vector3d& point);
  /// Drawn once per received frame (after SetFrame): exporters grab the framebuffer here.
  void frameDrawn(qint64 frame);

 protected:
  void initializeGL() override;
  void paintGL() override;
  void mousePressEvent(QMouseEvent* event) override;
  void mouseMoveEvent(QMouseEvent* event) override;
  void mouseReleaseEvent(QMouseEvent* event) override;
  void wheelEvent(QWheelEvent* event) override;
  void leaveEvent(QEvent* event) override;

 private:
  render::Ray RayAt(const QPointF& position) const;
  void FrameScene();
  void ReleaseRenderer();

  const SceneMirror* mirror_ = nullptr;
  std::vector<Eigen::Vector3f> cloth_;
  qint64 frame_ = -1;
  qint64 drawn_frame_ = -1;
  std::optional<render::DrawCursor> cursor_;
  double radius_ = 0.05;
  bool selection_visible_ = false;
  ViewColours colours_;
  render::Camera camera_;
  std::unique_ptr<render::SceneRenderer> renderer_;
  QString gl_info_;
  PointerGesture gesture_ = PointerGesture::kNone;
  QPointF last_pos_;
  Eigen::Vector3d grab_plane_point_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d grab_plane_normal_ = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d grab_now_ = Eigen::Vector3d::Zero();
};

}  // namespace costume::frontend
