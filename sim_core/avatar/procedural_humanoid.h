#pragma once
/// @file
/// The built-in avatar: an H-Anim humanoid with a smooth skinned surface, made without any
/// file, so the product runs on a machine with no assets.

#include <memory>

#include "sim_core/avatar/avatar.h"

namespace costume::sim {

/// Body measurements of the built-in humanoid [m].
struct HumanoidMeasures {
  double height = 1.75;
  /// Half widths of the torso at the chest, waist and hips (x) and their depths (z).
  double chest_half_width = 0.17;
  double waist_half_width = 0.14;
  double hip_half_width = 0.17;
  double chest_half_depth = 0.11;
  double waist_half_depth = 0.09;
  double hip_half_depth = 0.11;
  double thigh_radius = 0.085;
  double calf_radius = 0.055;
  double upper_arm_radius = 0.045;
  double forearm_radius = 0.037;
  double neck_radius = 0.055;
  double head_radius = 0.1;
};

/// The H-Anim skeleton of the built-in humanoid: every HAnimJoint, in a rest pose standing
/// on y = 0, facing +z, arms hanging at 20° from the body (an A-pose, as H-Anim suggests).
/// Joint i is HAnimJoint i, named by HAnimName (H-Anim 2.0: "l_talocrural"); x points to
/// the avatar's left (l_hip.x > 0). Every rest frame is aligned with the world (identity
/// rotation), so flexion is a rotation about x. Joint heights are fractions of `height`
/// from anthropometric tables. Throws InputError naming the field for a height outside
/// [0.5, 2.5] m or a width/radius outside [0.005, 0.25] × height.
std::shared_ptr<const Skeleton> MakeHumanoidSkeleton(const HumanoidMeasures& measures = {});

/// The built-in humanoid: that skeleton and a closed, smooth surface around it, skinned
/// with weights blended over the joints so it bends without creases.
/// Each body segment's surface is a closed mesh; the body is their union.
/// Sixteen meshes (every H-Anim segment but the root's), each a tube of superelliptic
/// cross-sections along its bone, closed by half-ellipsoid caps that reach into the
/// neighbouring segments; about 6,400 vertices at the default height. Across each joint the
/// weight passes smoothly from one segment's joint to the next over a few centimetres; away
/// from the joints each vertex follows its segment's joint alone. Throws as
/// MakeHumanoidSkeleton.
std::shared_ptr<const Avatar> MakeHumanoid(const HumanoidMeasures& measures = {});

}  // namespace costume::sim
