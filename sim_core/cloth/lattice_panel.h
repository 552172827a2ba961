#pragma once
/// @file
/// Rectangular lattice panels with the 12-neighbour springs of the paper's Figure 2a.

#include <Eigen/Core>
#include <string>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/material.h"

namespace costume::sim {

/// A flat rectangular panel sampled as a rows×cols lattice.
/// Particle (i, j) (row i, column j) sits at origin + j·du·u_axis + i·dv·v_axis with
/// du = width/(cols−1), dv = height/(rows−1); its index is i·cols + j.
struct LatticePanel {
  Eigen::Vector3d origin = Eigen::Vector3d(-0.5, 0.0, -0.5);
  /// Unit vector along the columns (j) [-].
  Eigen::Vector3d u_axis = Eigen::Vector3d::UnitX();
  /// Unit vector along the rows (i) [-]; must be orthogonal to u_axis.
  Eigen::Vector3d v_axis = Eigen::Vector3d::UnitZ();
  /// Extent along u_axis and v_axis [m] > 0.
  double width = 1.0;
  double height = 1.0;
  /// Lattice size, each >= 2.
  int cols = 33;
  int rows = 33;
};

/// Builds the model data of a panel: masses density·width·height spread evenly over the
/// particles (so the total is exact and N-independent), areas likewise, and springs:
/// - structural, 4-neighbourhood (i±1, j), (i, j±1): k = stretch_stiffness;
/// - shear, diagonals (i±1, j±1): k = shear_stiffness;
/// - bending, (i±2, j), (i, j±2): k = bending_rigidity / h², h the spacing along that axis;
/// each spring's damping c = damping·k, rest length the lattice distance. A per-spring
/// override in the material (structural_spring_k, ...) replaces the derived k.
/// Triangles split each lattice cell along alternating diagonals. Throws InputError for a
/// bad panel (naming `name`.field) or material.
ClothModelData BuildLatticePanel(const LatticePanel& panel, const Material& material,
                                 const std::string& name);

/// Indices of the particles nearest to each of `points` (one per point, same order).
/// Throws InputError naming `context` when a point has no particle within `tolerance` [m].
std::vector<int> FindNearestParticles(const Points& positions,
                                      const std::vector<Eigen::Vector3d>& points,
                                      double tolerance, const std::string& context);

}  // namespace costume::sim
