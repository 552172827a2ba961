#include "render/camera.h"

#include <algorithm>
#include <cmath>

namespace costume::render {
namespace {

constexpr double kPi = 3.14159265358979323846;

double Radians(double degrees) { return degrees * kPi / 180.0; }

// The camera's orthonormal frame: right, up and forward (towards the target).
struct Basis {
  Eigen::Vector3d right, up, forward;
};

Basis CameraBasis(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                  const Eigen::Vector3d& up) {
  Basis basis;
  basis.forward = (target - eye).normalized();
  basis.right = basis.forward.cross(up).normalized();
  basis.up = basis.right.cross(basis.forward);
  return basis;
}

// An up direction that is not parallel to `forward`: +y, or -z when looking straight down/up.
Eigen::Vector3d UpFor(const Eigen::Vector3d& forward) {
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  return std::abs(forward.normalized().dot(y)) > 0.999 ? Eigen::Vector3d(-Eigen::Vector3d::UnitZ())
                                                        : y;
}

}  // namespace

Eigen::Matrix4d Camera::View() const {
  const Basis basis = CameraBasis(eye, target, up);
  Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
  view.block<1, 3>(0, 0) = basis.right.transpose();
  view.block<1, 3>(1, 0) = basis.up.transpose();
  view.block<1, 3>(2, 0) = -basis.forward.transpose();
  view(0, 3) = -basis.right.dot(eye);
  view(1, 3) = -basis.up.dot(eye);
  view(2, 3) = basis.forward.dot(eye);
  return view;
}

Eigen::Matrix4d Camera::Projection(double aspect) const {
  const double f = 1.0 / std::tan(0.5 * Radians(fov_y_degrees));
  Eigen::Matrix4d projection = Eigen::Matrix4d::Zero();
  projection(0, 0) = f / aspect;
  projection(1, 1) = f;
  projection(2, 2) = (far_plane + near_plane) / (near_plane - far_plane);
  projection(2, 3) = 2.0 * far_plane * near_plane / (near_plane - far_plane);
  projection(3, 2) = -1.0;
  return projection;
}

Eigen::Matrix4d Camera::ViewProjection(double aspect) const {
  return Projection(aspect) * View();
}

Camera FrameBox(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& view_direction,
                double fov_y_degrees) {
  Camera camera;
  camera.fov_y_degrees = fov_y_degrees;
  const Eigen::Vector3d centre = box.center();
  const Eigen::Vector3d forward = view_direction.normalized();
  camera.up = UpFor(forward);
  const Basis basis = CameraBasis(centre - forward, centre, camera.up);
  // The distance at which every corner lies inside the square field of view (aspect 1, so
  // wider viewports fit too): |x| <= t·(d + z) and |y| <= t·(d + z) per corner, z being the
  // corner's depth beyond the centre.
  const double t = std::tan(0.5 * Radians(fov_y_degrees));
  double distance = 0.0;
  double radius = 0.5 * box.diagonal().norm();
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d offset = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(i)) -
                                   centre;
    const double x = std::abs(offset.dot(basis.right));
    const double y = std::abs(offset.dot(basis.up));
    const double z = offset.dot(basis.forward);
    distance = std::max(distance, std::max(x, y) / t - z);
  }
  radius = std::max(radius, 1e-3);
  distance = 1.05 * std::max(distance, radius + 1e-3);  // a thin margin around the box
  camera.target = centre;
  camera.eye = centre - distance * forward;
  camera.near_plane = std::max(0.5 * (distance - radius), 1e-3);
  camera.far_plane = 2.0 * (distance + radius);
  return camera;
}

std::optional<Eigen::Vector2d> ProjectToPixel(const Camera& camera, const Eigen::Vector3d& point,
                                              int width, int height) {
  const double aspect = static_cast<double>(width) / height;
  const Eigen::Vector4d clip = camera.ViewProjection(aspect) * point.homogeneous();
  if (clip.w() <= 0.0) return std::nullopt;
  const Eigen::Vector3d ndc = clip.head<3>() / clip.w();
  if (ndc.z() < -1.0 || ndc.z() > 1.0) return std::nullopt;
  return Eigen::Vector2d(0.5 * (ndc.x() + 1.0) * width, 0.5 * (1.0 - ndc.y()) * height);
}

Ray PixelRay(const Camera& camera, double x, double y, int width, int height) {
  const Basis basis = CameraBasis(camera.eye, camera.target, camera.up);
  const double t = std::tan(0.5 * Radians(camera.fov_y_degrees));
  const double aspect = static_cast<double>(width) / height;
  const double ndc_x = 2.0 * x / width - 1.0;
  const double ndc_y = 1.0 - 2.0 * y / height;
  const Eigen::Vector3d direction =
      basis.forward + ndc_x * t * aspect * basis.right + ndc_y * t * basis.up;
  return Ray{camera.eye, direction.normalized()};
}

void Orbit(Camera& camera, double yaw_radians, double pitch_radians) {
  const Eigen::Vector3d world_up = Eigen::Vector3d::UnitY();
  Eigen::Vector3d offset = camera.eye - camera.target;
  const double distance = offset.norm();
  if (!(distance > 0.0) || !std::isfinite(yaw_radians) || !std::isfinite(pitch_radians)) return;
  // Elevation above the horizontal plane, kept 1° short of the poles so the view never flips.
  const double max_elevation = Radians(89.0);
  const double elevation = std::asin(std::clamp(offset.dot(world_up) / distance, -1.0, 1.0));
  const double new_elevation = std::clamp(elevation - pitch_radians, -max_elevation, max_elevation);
  offset = Eigen::AngleAxisd(yaw_radians, world_up) * offset;
  const Eigen::Vector3d horizontal = offset - offset.dot(world_up) * world_up;
  const Eigen::Vector3d heading =
      horizontal.norm() > 1e-12 ? horizontal.normalized() : Eigen::Vector3d(Eigen::Vector3d::UnitZ());
  camera.eye = camera.target + distance * (std::cos(new_elevation) * heading +
                                           std::sin(new_elevation) * world_up);
  camera.up = world_up;
}

void Pan(Camera& camera, double dx, double dy) {
  if (!std::isfinite(dx) || !std::isfinite(dy)) return;
  const Basis basis = CameraBasis(camera.eye, camera.target, camera.up);
  const double distance = (camera.eye - camera.target).norm();
  const double view_height = 2.0 * distance * std::tan(0.5 * Radians(camera.fov_y_degrees));
  const Eigen::Vector3d shift = view_height * (dx * basis.right + dy * basis.up);
  camera.eye += shift;
  camera.target += shift;
}

void Zoom(Camera& camera, double factor) {
  if (!(factor > 0.0) || !std::isfinite(factor)) return;
  camera.eye = camera.target + (camera.eye - camera.target) / factor;
}

}  // namespace costume::render
