#pragma once
/// @file
/// A perspective camera and the helpers the thumbnails and the GUI's 3D view share: framing a
/// box, projecting points to pixels, rays through pixels (mouse picking), orbit, pan and zoom.
/// World frame: metres, y up (the avatar's frame).

#include <optional>

#include <Eigen/Dense>
#include <Eigen/Geometry>

namespace costume::render {

/// A pinhole camera looking from `eye` at `target`, `up` giving the screen's up direction.
struct Camera {
  Eigen::Vector3d eye{0, 1.2, 3.5};   ///< camera position [m]
  Eigen::Vector3d target{0, 1, 0};    ///< point at the centre of the view [m]
  Eigen::Vector3d up{0, 1, 0};        ///< approximate up direction (need not be unit)
  double fov_y_degrees = 35;          ///< vertical field of view [deg], in (0, 180)
  double near_plane = 0.05;           ///< near clipping distance [m], > 0
  double far_plane = 50;              ///< far clipping distance [m], > near_plane

  /// The OpenGL clip-space matrix projection × view for a viewport of width/height `aspect`.
  Eigen::Matrix4d ViewProjection(double aspect) const;
  /// The view matrix alone (world to camera, camera looking down -z).
  Eigen::Matrix4d View() const;
  /// The projection matrix alone (OpenGL convention, depth mapped to [-1, 1]).
  Eigen::Matrix4d Projection(double aspect) const;
};

/// A camera looking along `view_direction` (from the eye towards the box, need not be unit)
/// at the centre of `box`, far enough that the whole box is inside the view for any aspect
/// ratio >= 1 (the bounding sphere fits the vertical field of view). Near and far planes
/// are set around the box. Up is +y unless view_direction is vertical, then -z.
Camera FrameBox(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& view_direction,
                double fov_y_degrees = 35);

/// The pixel where `point` [m] appears in a width × height image: x to the right from the left
/// edge, y down from the top edge, pixel centres at half-integers (pixel (i, j) covers
/// [i, i+1) × [j, j+1)). Empty when the point is behind the eye or outside near..far.
/// The result may lie outside the image.
std::optional<Eigen::Vector2d> ProjectToPixel(const Camera& camera, const Eigen::Vector3d& point,
                                              int width, int height);

/// A ray in world coordinates [m]; direction is unit length.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};

/// The ray from the eye through image position (x, y) in the conventions of ProjectToPixel
/// (for mouse picking: pass the cursor position + 0.5 for the pixel's centre).
Ray PixelRay(const Camera& camera, double x, double y, int width, int height);

/// Turns the eye about the target: yaw about the world up axis (+y), pitch about the camera's
/// right axis [rad], both by the right-hand rule (positive yaw takes an eye on +z towards +x,
/// positive pitch lowers the eye). The eye's elevation stays within ±89°, so the view never
/// flips over the pole; up becomes +y.
void Orbit(Camera& camera, double yaw_radians, double pitch_radians);

/// Moves eye and target together in the view plane by dx (right) and dy (up), given as
/// fractions of the view's height at the target's distance.
void Pan(Camera& camera, double dx, double dy);

/// Moves the eye towards the target: the distance is divided by `factor` (> 1 zooms in).
/// Non-positive or non-finite factors are ignored.
void Zoom(Camera& camera, double factor);

}  // namespace costume::render
