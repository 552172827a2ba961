#pragma once
/// @file
/// Fitting a mesh garment out of the body before the simulation starts (mode A, paper §6).
/// A garment modelled on the skin with no thickness (MakeHuman's suits) starts inside the
/// collider's shell (skin + cloth thickness) almost everywhere; left there, the position
/// correction throws it out in one step against rest lengths measured inside, which tears
/// it. Here the mesh itself is moved out first, and the cloth is then built on the moved
/// mesh, so its rest lengths are those of the fitted shape: nothing is pre-stretched.

#include <Eigen/Core>
#include <vector>

#include "sim_core/cloth/mesh_cloth.h"

namespace costume::sim {

/// What FitOutsideBody did.
struct GarmentFitReport {
  /// Vertices closer to the skin than the clearance (or inside) before the fit.
  int num_too_close = 0;
  /// Deepest vertex inside the skin before the fit [m] (0 when none was inside).
  double max_depth_before = 0.0;
  /// Largest distance a vertex was moved [m].
  double max_move = 0.0;
  /// Smallest signed distance to the skin after the fit [m] (vertices within the search
  /// reach only).
  double min_distance_after = 0.0;
};

/// `mesh` with every vertex at least `clearance` [m] >= 0 outside the closed surface
/// (`body_vertices` n×3 [m], `body_triangles` counter-clockwise from outside; the avatar in
/// the pose the garment was modelled on). Rounds of: each vertex nearer than the clearance
/// (or inside, up to 10 cm deep) moves along the skin's normal to the clearance; then the
/// displacements are smoothed over the mesh's edges (each vertex's becomes the mean of its
/// own and its neighbours'), so that the cloth around a pushed patch follows it instead of
/// folding at its edge. A last push without smoothing leaves every vertex within reach at
/// the clearance or beyond. Vertices and faces keep their order. Throws InputError (from
/// MeshDistance) when the body surface is not closed, and for a negative or non-finite
/// clearance.
SurfaceMesh FitOutsideBody(const SurfaceMesh& mesh, const Points& body_vertices,
                           const std::vector<Eigen::Vector3i>& body_triangles, double clearance,
                           GarmentFitReport* report = nullptr);

/// The vertices of the mesh's open boundary loops whose mean height (y) lies within `band`
/// [m] of `height` [m]: the waistband of trousers or a skirt fitted to the body, where the
/// garment is held (GarmentSpec::pin_points with attach_to).
std::vector<Eigen::Vector3d> WaistbandPoints(const SurfaceMesh& mesh, double height, double band);

}  // namespace costume::sim
