#pragma once
/// @file
/// Curvature-adaptive regions on the CLOTH (paper §4; DESIGN.md "Collision"): the cloth is
/// split into base regions of about N×N particles, organised as a quadtree-like hierarchy
/// (up to four neighbouring regions per parent). Every frame each node gets the box of its
/// particles' query boxes and the normal cone of its triangles (Provot 1997: an axis and a
/// half angle holding every triangle normal); walking the hierarchy top down, a node whose
/// cone is within a flatness angle is taken whole, so a flat piece of cloth costs one
/// broad-phase query against the body, while folded cloth descends to its base regions.
/// The hierarchy is built once on the rest topology; only boxes and cones change.

#include <Eigen/Core>
#include <vector>

#include "sim_core/cloth/cloth_model.h"

namespace costume::sim {

/// One node of the hierarchy: a base region (no children) or the union of its children.
struct ClothRegionNode {
  /// Its particles: slots [first, first + count) of ClothRegions::particles().
  int first = 0;
  int count = 0;
  /// Its children: nodes [first_child, first_child + num_children); 0 children for a base
  /// region. Children always have larger indices than their parent.
  int first_child = 0;
  int num_children = 0;
  /// Its parent node, −1 for a root.
  int parent = -1;
  /// Base regions only: its triangles (those whose first corner is one of its particles),
  /// slots [first_triangle, first_triangle + num_triangles) of ClothRegions::triangles().
  int first_triangle = 0;
  int num_triangles = 0;

  // ---- refitted every frame by ClothRegions::Refit ----
  /// Box of its particles' query boxes [m]; empty (min > max) when none is valid.
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d box_max = Eigen::Vector3d::Zero();
  /// Normal cone: unit axis [-] and half angle [rad] in [0, π] holding every triangle
  /// normal below the node; π when undefined (normals cancelling out).
  Eigen::Vector3d cone_axis = Eigen::Vector3d::UnitY();
  double cone_angle = 0.0;
  /// Twice the triangle area under the node [m²]: the weight of its axis in its parent's.
  double cone_weight = 0.0;
};

/// The cloth's region hierarchy and its per-frame boxes and cones.
class ClothRegions {
 public:
  /// Builds the hierarchy from the cloth's rest topology. Base regions: lattice blocks of
  /// about region_size × region_size particles when the model is a lattice
  /// (lattice_rows·lattice_cols = num_particles), merged 2 × 2 per level; otherwise
  /// regions of up to region_size² particles grown breadth first over the triangles'
  /// edges, each level joining a region with up to three neighbours. Throws InputError
  /// naming the cloth for region_size outside 1..256.
  ClothRegions(const ClothModel& cloth, int region_size);

  int num_particles() const { return static_cast<int>(particles_.size()); }
  int num_nodes() const { return static_cast<int>(nodes_.size()); }
  int num_base_regions() const { return num_base_regions_; }
  /// Roots are nodes [0, num_roots()) (one per connected piece of cloth, or one in all).
  int num_roots() const { return num_roots_; }
  /// Levels below the deepest root [-]: 0 when every root is a base region.
  int max_depth() const { return max_depth_; }
  const std::vector<ClothRegionNode>& nodes() const { return nodes_; }
  /// Particle indices grouped so that every node's particles are one contiguous range.
  const std::vector<int>& particles() const { return particles_; }
  /// Triangle indices grouped by base region.
  const std::vector<int>& triangles() const { return triangles_; }

  /// Recomputes every node's box and, if `cones`, its normal cone. Particle i covers the
  /// box positions.row(i) ± half_extents[i] (num_particles() values [m]); a particle with
  /// a negative half extent is left out of the boxes. `positions` must have
  /// num_particles() rows. With `cone_period` > 1 only one base region in every
  /// cone_period refreshes its cone, in turns (all of them at the first call with cones):
  /// the boxes are exact every call, the cones up to cone_period − 1 calls old, which is
  /// enough to choose how coarsely to query (the contacts do not depend on it). Parents'
  /// cones follow their children's every call. Returns the cone tests done (one per
  /// triangle of a refreshed base region, one per child of a parent), for
  /// BodyCollisionStats::num_tests. Never throws; never allocates.
  long long Refit(const Points& positions, const double* half_extents, bool cones = true,
                  int cone_period = 1);

  /// The nodes to query after Refit, walking top down: a base region, or a node whose
  /// cone half angle is at most `flatness_angle` [rad] (taken whole, its descendants
  /// not visited). Together they hold every particle exactly once. Never throws; never
  /// allocates.
  const std::vector<int>& Select(double flatness_angle);

 private:
  std::vector<ClothRegionNode> nodes_;
  std::vector<int> particles_;
  std::vector<int> triangles_;
  std::vector<Eigen::Vector3i> corners_;  // the model's triangles
  int num_base_regions_ = 0;
  int num_roots_ = 0;
  int max_depth_ = 0;
  std::vector<Eigen::Vector3d> normals_;  // Refit scratch, by slot of triangles_
  std::vector<double> norms_;
  std::vector<char> reached_;             // Select scratch
  int cone_phase_ = 0;                    // which base regions refresh their cone next
  bool cones_current_ = false;            // the last Refit computed cones
  std::vector<int> selected_;
};

}  // namespace costume::sim
