#include "frontend/view_widget.h"

#include <QMouseEvent>
#include <QOpenGLContext>
#include <QSurfaceFormat>
#include <QWheelEvent>
#include <cmath>
#include <exception>

#include "frontend/picking.h"

namespace costume::frontend {
namespace {

/// Pixels of drag per radian of orbit.
constexpr double kPixelsPerRadian = 300.0;

}  // namespace

ViewWidget::ViewWidget(QWidget* parent) : QOpenGLWidget(parent) {
  QSurfaceFormat format;
  format.setVersion(3, 3);
  format.setProfile(QSurfaceFormat::CoreProfile);
  format.setDepthBufferSize(24);
  format.setSamples(4);
  setFormat(format);
  setMouseTracking(true);
  setMinimumSize(320, 240);
}

ViewWidget::~ViewWidget() {
  // QOpenGLWidget's own destructor destroys the context after this one has run, and the
  // context's aboutToBeDestroyed would then call ReleaseRenderer on what is no longer a
  // ViewWidget (UndefinedBehaviorSanitizer: "member call ... not an object of type
  // 'ViewWidget'"): cut that connection first, and release here, with the context alive.
  if (QOpenGLContext* gl = context()) disconnect(gl, nullptr, this, nullptr);
  ReleaseRenderer();
}

void ViewWidget::ReleaseRenderer() {
  if (!renderer_) return;
  // The renderer's GL objects belong to this widget's context: delete them with it current.
  makeCurrent();
  renderer_.reset();
  doneCurrent();
}

void ViewWidget::SetMirror(const SceneMirror* mirror) {
  mirror_ = mirror;
  cloth_ = mirror ? mirror->rest_positions() : std::vector<Eigen::Vector3f>{};
  FrameScene();
  update();
}

void ViewWidget::FrameScene() {
  if (!mirror_) return;
  // From the front (+z), a little above: the avatar faces +z.
  camera_ = render::FrameBox(mirror_->Bounds(), Eigen::Vector3d(0.0, -0.25, -1.0));
}

void ViewWidget::SetFrame(const ClothFrame& frame) {
  if (mirror_ && static_cast<int>(frame.positions.size()) != mirror_->num_particles()) return;
  cloth_ = frame.positions;
  frame_ = frame.frame;
  update();
}

void ViewWidget::SetCursor(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                           bool glove) {
  render::DrawCursor cursor;
  cursor.position = position;
  cursor.orientation = orientation;
  cursor.shape = glove ? render::CursorShape::kHand : render::CursorShape::kCone;
  cursor.size = glove ? 0.12 : 0.06;
  cursor_ = cursor;
  update();
}

void ViewWidget::HideCursor() {
  cursor_.reset();
  update();
}

std::optional<Eigen::Vector3d> ViewWidget::grab_point() const {
  if (gesture_ != PointerGesture::kGrab) return std::nullopt;
  return grab_now_;
}

render::RenderScene ViewWidget::BuildScene() const {
  render::RenderScene scene;
  scene.background = colours_.background;
  if (mirror_) scene.floor_height = mirror_->floor_height();
  if (mirror_ && mirror_->has_avatar()) {
    render::DrawMesh avatar;
    avatar.positions = mirror_->avatar_vertices();
    avatar.indices = mirror_->avatar_indices();
    avatar.colour = colours_.avatar;
    scene.meshes.push_back(std::move(avatar));
  }
  if (mirror_ && !cloth_.empty()) {
    render::DrawMesh cloth;
    cloth.positions = cloth_;
    cloth.indices = mirror_->cloth_indices();
    cloth.colour = colours_.cloth;
    cloth.two_sided = true;
    scene.meshes.push_back(std::move(cloth));
  }
  const std::optional<Eigen::Vector3d> grab = grab_point();
  if (selection_visible_ && (grab || cursor_)) {
    render::DrawSphere sphere;
    sphere.centre = grab ? *grab : cursor_->position;
    sphere.radius = radius_;
    scene.selection = sphere;
  }
  scene.cursor = cursor_;
  return scene;
}

void ViewWidget::initializeGL() {
  QOpenGLContext* gl = context();
  try {
    renderer_ = std::make_unique<render::SceneRenderer>(
        [gl](const char* name) { return reinterpret_cast<void*>(gl->getProcAddress(name)); });
    gl_info_ = QString::fromUtf8(renderer_->GlVersion());
  } catch (const std::exception& error) {
    gl_info_ = QString("OpenGL 3.3 core renderer not available: ") + error.what();
    renderer_.reset();
  }
  connect(gl, &QOpenGLContext::aboutToBeDestroyed, this, [this] { ReleaseRenderer(); },
          Qt::DirectConnection);
}

void ViewWidget::paintGL() {
  if (!renderer_) return;
  const qreal ratio = devicePixelRatioF();
  const int w = std::max(1, static_cast<int>(std::lround(width() * ratio)));
  const int h = std::max(1, static_cast<int>(std::lround(height() * ratio)));
  renderer_->Draw(BuildScene(), camera_, w, h);
  if (frame_ != drawn_frame_) {
    drawn_frame_ = frame_;
    emit frameDrawn(frame_);
  }
}

render::Ray ViewWidget::RayAt(const QPointF& position) const {
  // Widget coordinates (logical pixels) with the pixel centre at +0.5, as PixelRay expects.
  return render::PixelRay(camera_, position.x() + 0.5, position.y() + 0.5, width(), height());
}

void ViewWidget::mousePressEvent(QMouseEvent* event) {
  last_pos_ = event->position();
  const bool shift = event->modifiers() & Qt::ShiftModifier;
  if (event->button() == Qt::MiddleButton || (event->button() == Qt::LeftButton && shift)) {
    gesture_ = PointerGesture::kPan;
    return;
  }
  if (event->button() != Qt::LeftButton) return;
  const render::Ray ray = RayAt(event->position());
  const std::optional<Hit> hit =
      mirror_ ? PickTriangles(ray.origin, ray.direction, cloth_, mirror_->cloth_indices())
              : std::nullopt;
  if (!hit) {
    gesture_ = PointerGesture::kOrbit;
    return;
  }
  gesture_ = PointerGesture::kGrab;
  grab_plane_point_ = hit->point;
  grab_plane_normal_ = (camera_.eye - camera_.target).normalized();
  grab_now_ = hit->point;
  emit pointerSample(grab_now_, 1, true);
  emit grabStarted(grab_now_);
  update();
}

void ViewWidget::mouseMoveEvent(QMouseEvent* event) {
  const QPointF delta = event->position() - last_pos_;
  last_pos_ = event->position();
  switch (gesture_) {
    case PointerGesture::kOrbit:
      render::Orbit(camera_, -delta.x() / kPixelsPerRadian, -delta.y() / kPixelsPerRadian);
      break;
    case PointerGesture::kPan:
      render::Pan(camera_, -delta.x() / std::max(1, height()), delta.y() / std::max(1, height()));
      break;
    case PointerGesture::kGrab: {
      const render::Ray ray = RayAt(event->position());
      if (const auto p = RayPlane(ray.origin, ray.direction, grab_plane_point_,
                                  grab_plane_normal_)) {
        grab_now_ = *p;
        emit pointerSample(grab_now_, 1, true);
      }
      break;
    }
    case PointerGesture::kNone: {
      // Hovering: the mouse device follows the cloth under the pointer (cursor shown).
      const render::Ray ray = RayAt(event->position());
      if (!mirror_) return;
      if (const auto hit =
              PickTriangles(ray.origin, ray.direction, cloth_, mirror_->cloth_indices())) {
        emit pointerSample(hit->point, 0, true);
      }
      return;
    }
  }
  update();
}

void ViewWidget::mouseReleaseEvent(QMouseEvent* event) {
  if (gesture_ == PointerGesture::kGrab && event->button() == Qt::LeftButton) {
    emit pointerSample(grab_now_, 0, true);
    emit grabEnded(grab_now_);
  }
  gesture_ = PointerGesture::kNone;
  update();
}

void ViewWidget::wheelEvent(QWheelEvent* event) {
  // One notch (120 units) zooms by 10 %.
  render::Zoom(camera_, std::pow(1.1, event->angleDelta().y() / 120.0));
  update();
}

void ViewWidget::leaveEvent(QEvent* event) {
  if (gesture_ != PointerGesture::kGrab) emit pointerSample(grab_now_, 0, false);
  QOpenGLWidget::leaveEvent(event);
}

}  // namespace costume::frontend
