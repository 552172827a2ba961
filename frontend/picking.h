#pragma once
/// @file
/// The mouse as a pointing device (paper §5 with a mouse for a stylus): which cloth point is
/// under the pointer, and where the pointer is while dragging. The GUI casts the ray through
/// the pointer (render::PixelRay) against the cloth's triangles to grab, then maps later
/// rays onto the plane through the grabbed point facing the camera, so the grabbed point
/// stays under the pointer.

#include <Eigen/Dense>
#include <cstdint>
#include <optional>
#include <vector>

namespace costume::frontend {

/// Where a ray hit a triangle mesh.
struct Hit {
  double distance = 0.0;       ///< along the (unit) ray direction from its origin [m]
  Eigen::Vector3d point;       ///< the hit point [m]
  int triangle = -1;           ///< index of the triangle hit (indices[3·triangle ...])
};

/// The nearest intersection of the ray (`origin` [m], unit `direction`) with the triangles
/// (`indices`, 3 per triangle, into `positions` [m]), both faces counting; empty when the ray
/// misses. Triangles with an index out of range are skipped. Möller–Trumbore per triangle.
std::optional<Hit> PickTriangles(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                 const std::vector<Eigen::Vector3f>& positions,
                                 const std::vector<std::uint32_t>& indices);

/// Where the ray meets the plane through `plane_point` with normal `plane_normal` (need not be
/// unit); empty when the ray is parallel to the plane or meets it behind its origin.
std::optional<Eigen::Vector3d> RayPlane(const Eigen::Vector3d& origin,
                                        const Eigen::Vector3d& direction,
                                        const Eigen::Vector3d& plane_point,
                                        const Eigen::Vector3d& plane_normal);

}  // namespace costume::frontend
