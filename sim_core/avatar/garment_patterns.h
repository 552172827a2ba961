#pragma once
/// @file
/// Built-in garments (skirt, cape, dress) made of lattice panels placed around an avatar in
/// its rest pose and sewn at their seams, so the product dresses an avatar with no file.
/// A panel's rest shape is its placed shape (a curved panel stands for a pattern piece with
/// darts); sewing welds the coincident particles of neighbouring panels' edges.

#include <memory>
#include <string>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/hanim.h"
#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/material.h"

namespace costume::sim {

/// Horizontal cross-section of the body at one height [m]: centre and half extents along x
/// (side to side) and z (front to back).
struct BodySection {
  double height = 0.0;
  double centre_x = 0.0;
  double centre_z = 0.0;
  double half_width = 0.0;
  double half_depth = 0.0;
};

/// The skin of the trunk and legs (arms, neck and head left out) in a horizontal slab: the
/// points a garment's ring at that height must enclose [m].
struct BodySlice {
  double height = 0.0;
  /// (x, z) of the skin vertices within the slab.
  std::vector<Eigen::Vector2d> points;
};

/// Where a garment goes on an avatar in its rest pose (y up, facing +z) [m].
struct BodyMeasures {
  BodySection shoulders;  // at the shoulder joints, torso only (arms excluded)
  BodySection chest;      // a third of the way from the shoulders down to the waist
  BodySection waist;      // at vl5
  BodySection hips;       // at the hip joints, thighs included
  double knee_height = 0.5;
  /// Slices every 2 cm from below the knees to above the shoulders, top first: every ring of
  /// a garment is widened until it encloses its slice plus the gap, so a garment never
  /// starts inside the body however its design rings are drawn.
  std::vector<BodySlice> slices;
};

/// Measures the rest skin of `avatar` around its H-Anim joints. Throws InputError naming the
/// avatar and what is missing when it lacks vl5, vc7, both hips, both knees or both
/// shoulders, has no skin at one of the measured heights, does not stand upright in its rest
/// pose (knees, hips, vl5, shoulders rising in that order: an up axis misread) or is not of
/// human size (0.3 to 3 m tall: a unit misread).
BodyMeasures MeasureBody(const Avatar& avatar);

/// A built-in garment: its model data (pins left empty) and the particles held to the body.
struct GarmentPattern {
  ClothModelData data;
  /// Particles attached to the body (the waistband, the cape's collar, the dress's top):
  /// they follow `attached_to`'s rigid motion instead of being simulated.
  std::vector<int> attached;
  HAnimJoint attached_to = HAnimJoint::kSacroiliac;
};

/// Names of the built-in garments: "skirt", "cape", "dress".
const std::vector<std::string>& BuiltInGarmentNames();

/// The built-in garment `name` for a body of `measures`, of `material`, with about
/// `resolution` particles along its circumference (>= 8; the total is about 1.2 ×
/// resolution² / 2 for the skirt). Kept `gap` [m] off the skin. Throws InputError listing the
/// valid names for an unknown one, or naming the field for a bad resolution or gap.
GarmentPattern MakeBuiltInGarment(const std::string& name, const BodyMeasures& measures,
                                  const Material& material, int resolution = 64,
                                  double gap = 0.015);

}  // namespace costume::sim
