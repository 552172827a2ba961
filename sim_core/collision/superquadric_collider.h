#pragma once
/// @file
/// The paper's fast avatar collision method (§4, DESIGN.md "Collision"): one superquadric
/// per H-Anim body segment, fitted to that segment's skin (Solina & Bajcsy 1990), with the
/// skin's distance from the superquadric stored as a map over the superquadric's surface.
///
/// Approximations, all deliberate:
/// - Each segment moves rigidly with its H-Anim joint. Linear blend skinning bends the skin
///   near the joints (elbows, knees, shoulders) in ways no rigid transform follows; there the
///   shell is off by up to the skin's blend displacement (centimetres at a bent elbow). The
///   skinned vertices passed to Update are not used.
/// - Distances are radial: measured along the ray from the superquadric's centre, as the
///   paper's map stores them. The thickness, a normal distance, becomes radial through the
///   cosine between the ray and the skin's normal stored in the map, and so does a radial
///   gap become the normal gap the solver's contact needs (exact for a locally flat skin).
/// - The contact normal is, by default, the superquadric's normalised gradient at the
///   particle's ray (the paper's choice), not the skin's normal; they differ where the skin
///   departs from the superquadric (measured on a capsule: 23° on its hemispherical cap,
///   0.4° mid-cylinder; docs/collision.md). ContactNormal::kSkin takes the map's
///   interpolated skin normal instead.
/// - The body's velocity at a particle is that of the point rigidly attached to the segment
///   at the particle's position, from the change of the joint frame between Update calls.

#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/hanim.h"
#include "sim_core/collision/body_collider.h"
#include "sim_core/collision/superquadric.h"

namespace costume::sim {

/// Options of the superquadric collider's construction.
struct SuperquadricColliderOptions {
  /// A segment with fewer skin vertices than this gets no superquadric [-] >= 11.
  int min_vertices_per_segment = 20;
  /// Distance map resolution: intervals over eta ∈ [−π/2, π/2] and over omega ∈ [−π, π) [-]
  /// >= 4.
  int map_eta_intervals = 32;
  int map_omega_intervals = 64;
  SuperquadricFitOptions fit;
  /// Where contact normals come from (see the file comment).
  enum class ContactNormal { kSuperquadricGradient, kSkin };
  ContactNormal contact_normal = ContactNormal::kSuperquadricGradient;
};

/// The superquadric fit of one H-Anim segment of an avatar.
struct SegmentSuperquadricFit {
  HAnimJoint segment = HAnimJoint::kHumanoidRoot;
  /// Index of the segment's joint in the avatar's skeleton.
  int joint = -1;
  /// Skin vertices whose dominant joint belongs to the segment (Avatar::vertex_segments).
  int num_vertices = 0;
  /// False when the segment had fewer than the minimum vertices; `fit` is then empty.
  bool fitted = false;
  /// The superquadric relative to the joint's frame, and its residuals [m].
  SuperquadricFit fit;
};

/// Fits one superquadric to each H-Anim segment of `avatar` that has skin vertices: the
/// segment's rest vertices expressed in its joint's rest frame. Returns one entry per such
/// segment in HAnimJoint order, with `fitted` false (and no fit) for segments with fewer than
/// `options.min_vertices_per_segment` vertices. Throws InputError for bad options.
std::vector<SegmentSuperquadricFit> FitAvatarSegments(
    const Avatar& avatar, const SuperquadricColliderOptions& options = {});

/// The skin around one superquadric, sampled on a regular (eta, omega) grid of its surface:
/// node (j, k) is the ray from the centre through ParametricSurfacePoint(eta_j, omega_k),
/// eta_j = −π/2 + j·π/num_eta, omega_k = −π + k·2π/num_omega (periodic in k).
struct SkinDistanceMap {
  int num_eta = 0;    ///< intervals along eta; nodes 0..num_eta
  int num_omega = 0;  ///< intervals (= nodes) along omega
  /// Per node, row-major (num_eta + 1)×num_omega: the skin's signed radial distance from the
  /// superquadric surface along the node's ray [m] (> 0: skin outside the superquadric).
  std::vector<double> skin_offset;
  /// Per node: the skin's outward unit normal where the ray leaves the skin, superquadric
  /// frame [-].
  std::vector<Eigen::Vector3d> skin_normal;
  /// Nodes whose ray missed the skin (open ends of a segment's skin), filled from their
  /// neighbours [-].
  int num_filled_nodes = 0;
  /// Per node: the skin triangle its ray hit (avatar vertex indices, −1 for filled nodes)
  /// and the hit's barycentric weights. Through them the map follows the skinned surface
  /// every frame (TrackSkin), so linear blend skinning's bending near joints, which a rigid
  /// superquadric cannot follow, is still collided with.
  std::vector<Eigen::Vector3i> hit_vertices;
  std::vector<Eigen::Vector3d> hit_weights;
  /// Per node: the ray's unit direction and the superquadric's radius along it [m].
  std::vector<Eigen::Vector3d> ray;
  std::vector<double> surface_radius;
};

/// One segment as the collider sees it.
struct SuperquadricSegment {
  HAnimJoint segment = HAnimJoint::kHumanoidRoot;
  int joint = -1;
  Superquadric superquadric;  ///< frame relative to the joint's frame
  SkinDistanceMap map;
  /// Radius of a sphere about the superquadric's centre holding the segment's skin and its
  /// shell (skin + the collider's thickness) [m]; grows when the tracked skin moves out.
  double bounding_radius = 0.0;
  /// The bounding radius in the rest pose and the largest skin offset then [m].
  double rest_bounding_radius = 0.0;
  double rest_max_offset = 0.0;
  /// RMS radial distance of the skin vertices from the superquadric [m].
  double fit_rms = 0.0;
  int num_vertices = 0;
};

/// A sphere centred on a joint between two fitted segments: the skin that linear blend
/// skinning bends around a joint (the front of a bent knee) moves beyond both rigid
/// superquadrics' maps, so the joint itself carries a sphere of the skin's radius there.
struct JointSphere {
  int joint = -1;
  /// The skin's distance from the joint centre across the bone (20th percentile of the
  /// vertices within 2 cm of the joint's cross-section plane, so it stays inside the skin) [m].
  double radius = 0.0;
};

/// Where a point is relative to one segment's skin shell (skin + thickness).
struct ShellProbe {
  /// Radial gap from the shell [m]: |q| − shell radius along the ray; < 0 inside.
  double radial_gap = 0.0;
  /// The gap converted to the skin's normal direction [m] (radial gap · cosine).
  double normal_gap = 0.0;
  /// Cosine between the ray and the skin normal, floored at 0.1 [-].
  double cosine = 1.0;
  /// Unit ray direction from the superquadric's centre, superquadric frame [-].
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  /// Shell radius along the ray [m].
  double shell_radius = 0.0;
  /// Outward unit normal of the superquadric (its normalised gradient) and the skin's
  /// (bilinear in the map, normalised), superquadric frame [-].
  Eigen::Vector3d gradient_normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d skin_normal = Eigen::Vector3d::UnitZ();
};

/// Probes the shell of `segment` at `q` (superquadric frame) [m]. Never throws or allocates.
void ProbeShell(const SuperquadricSegment& segment, const Eigen::Vector3d& q, double thickness,
                ShellProbe& probe);

class SuperquadricCollider : public BodyCollider {
 public:
  /// Fits the segments of `avatar` and builds their distance maps by casting each map node's
  /// ray against the segment's skin triangles (those with at least two vertices in the
  /// segment). The body starts in the rest pose. Throws InputError for a null avatar, bad
  /// settings or options.
  SuperquadricCollider(std::shared_ptr<const Avatar> avatar,
                       const BodyCollisionSettings& settings = {},
                       const SuperquadricColliderOptions& options = {});

  /// See BodyCollider. `joint_world` has one frame per skeleton joint; a call with fewer
  /// frames, or a non-positive or non-finite dt after the first call, keeps the previous pose
  /// and sets the body's velocity to zero. Never throws or allocates.
  void Update(const std::vector<Eigen::Isometry3d>& joint_world, const Points& skinned_vertices,
              double dt) override;

  /// See BodyCollider. The test is against the body at the start of the step (the pose
  /// before the last Update), the particle's predicted normal gap being
  /// gap + h·(v − v_body)·n; the target normal velocity is v_body·n − gap/h, the body surface's
  /// normal velocity plus the correction that brings the particle onto the shell within the
  /// step (as sphere_contacts.cc, for a moving surface). One contact per particle: its most
  /// penetrating segment. Segments whose bounding sphere (grown by the motion of the step)
  /// misses the particles' bounding box are skipped; stats().num_tests counts the
  /// particle-segment pairs examined. Preconditions: h > 0, velocities the size of
  /// positions. Never throws; allocates only when `contacts` grows.
  void FindContacts(const Points& positions, const Points& velocities, double h, double margin,
                    std::vector<Contact>& contacts) override;

  /// See BodyCollider. Against the body at the end of the step (the last Update): a particle
  /// inside a segment's shell moves along that segment's ray onto the shell, and its velocity
  /// into the body (relative to the body's surface velocity) is removed. Returns the deepest
  /// radial penetration [m]. Never throws or allocates.
  double ProjectOut(Points& positions, Points& velocities) override;

  BodyCollisionStats stats() const override { return stats_; }

  /// The segments that got a superquadric.
  const std::vector<SuperquadricSegment>& segments() const { return segments_; }
  /// The spheres on joints between two fitted segments.
  const std::vector<JointSphere>& joint_spheres() const { return spheres_; }
  /// The segments that had skin vertices but fewer than the minimum, so no superquadric:
  /// their skin is not collided with.
  const std::vector<HAnimJoint>& skipped_segments() const { return skipped_; }
  /// A segment's superquadric frame in the world at the start / end of the coming step.
  const Eigen::Isometry3d& start_frame(int segment) const { return start_[segment].to_world; }
  const Eigen::Isometry3d& end_frame(int segment) const { return end_[segment].to_world; }

 private:
  /// A segment's superquadric frame in the world and its inverse.
  struct Placement {
    Eigen::Isometry3d to_world = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d to_local = Eigen::Isometry3d::Identity();
  };
  void SetPose(const std::vector<Eigen::Isometry3d>& joint_world, std::vector<Placement>& out);
  /// Segments whose bounding sphere grown by `reach` [m] meets the box [lo, hi].
  void CullSegments(const std::vector<Placement>& placements, const Eigen::Vector3d& lo,
                    const Eigen::Vector3d& hi, double reach);
  /// The deepest shell among the segments and joint spheres at `x` (world), at the start or
  /// the end of the step: its normal gap [m], outward normal and surface velocity there.
  /// Shells farther than `reach` [m] plus their own motion over the step are skipped;
  /// returns false when every shell was.
  bool DeepestShell(const Eigen::Vector3d& x, bool at_end, double reach, double& gap,
                    Eigen::Vector3d& normal, Eigen::Vector3d& body_velocity);
  /// Moves every map node's skin point to where skinning put it: `skinned` (n×3) in the
  /// segment's end-of-step frame. Never allocates.
  void TrackSkin(const Points& skinned);
  /// Velocity [m/s] of the body point of `segment` that is at `x` (world) at the start of
  /// the step (`at_end` false) or at its end (true), over the step's rigid motion.
  Eigen::Vector3d BodyVelocity(int segment, const Eigen::Vector3d& x, bool at_end) const;

  std::shared_ptr<const Avatar> avatar_;
  BodyCollisionSettings settings_;
  bool skin_normals_ = false;
  std::vector<SuperquadricSegment> segments_;
  std::vector<JointSphere> spheres_;
  /// Joint-sphere centres at the start and end of the step [m].
  std::vector<Eigen::Vector3d> sphere_start_, sphere_end_;
  std::vector<HAnimJoint> skipped_;
  std::vector<Placement> start_;
  std::vector<Placement> end_;
  /// start → end motion of each segment and its speed bound (translation of the centre plus
  /// bounding radius times rotation angle) [m].
  std::vector<Eigen::Isometry3d> motion_;
  std::vector<double> sweep_;
  double inverse_dt_ = 0.0;
  bool has_pose_ = false;
  std::vector<int> active_;
  BodyCollisionStats stats_;
};

}  // namespace costume::sim
