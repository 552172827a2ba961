#pragma once
/// @file
/// The paper's fast avatar collision method (§4, DESIGN.md "Collision"): one superquadric
/// per H-Anim body segment, fitted to that segment's skin (Solina & Bajcsy 1990), with the
/// skin's distance from the superquadric stored as a map over the superquadric's surface.
///
/// The map is redrawn every frame from the skinned triangles (lazily, when cloth first comes
/// near the segment), so it follows linear blend skinning where it bends the skin away from
/// the rigid segments (hips, knees, elbows); a drawing of a skin seen before (a looping clip's
/// later passes) is reused from a store (skin_map_cache.h). A drawing rasterises again only
/// the skin that moved in the segment's frame since it last did; the exits of the rest come
/// from a still layer. docs/collision.md has the measurements.
///
/// Approximations, all deliberate:
/// - Each segment's shell is star-shaped from its superquadric's centre (moved inside the
///   skin where the fit leaves it outside): along every ray it reaches the first place where
///   the ray leaves the skin, among the triangles of the segment and of its H-Anim
///   neighbours, and at most the segment's reach (the farthest skin it holds plus 6 cm); the
///   neighbours' shells hold the skin beyond. A joint shell per joint between two fitted
///   segments, star-shaped from the joint, holds the creases of bent joints, which no
///   segment's centre sees. Skin that neither any centre nor any joint sees is held by no
///   shell.
/// - Where a map's rays saw no skin within the reach, a reading inside the shell is trusted
///   only as deep as the step's motion allows (none when all four nodes are such).
/// - A body made of overlapping closed pieces (the built-in humanoid) has surfaces inside
///   other pieces; the parts of them more than 1.5 mm inside another piece in the rest pose
///   are not skin. The pieces' overlap is taken from the rest pose.
/// - Distances are radial: measured along the ray from the superquadric's centre, as the
///   paper's map stores them. The thickness, a normal distance, becomes radial through the
///   cosine between the ray and the skin's normal stored in the map, and so does a radial
///   gap become the normal gap the solver's contact needs (exact for a locally flat skin).
/// - Between map nodes the skin's radius and normal are interpolated bilinearly; a cell that
///   straddles a silhouette seen from the centre is read as its nearest skin, which leaves
///   a band of up to a cell's width of the farther skin (a crease's far side) out of that
///   shell.
/// - The contact normal is, by default, the superquadric's normalised gradient at the
///   particle's ray (the paper's choice), not the skin's normal; they differ where the skin
///   departs from the superquadric (measured on a capsule: 23° on its hemispherical cap,
///   0.4° mid-cylinder; docs/collision.md). ContactNormal::kSkin takes the map's
///   interpolated skin normal instead.
/// - The body's velocity at a particle is that of the point rigidly attached to the segment
///   at the particle's position, from the change of the joint frame between Update calls;
///   the skin's own motion relative to the segment (skinning) enters as the change of the
///   map: contacts test the start-of-step placement carrying the end-of-step map.

#include <Eigen/Geometry>
#include <array>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/hanim.h"
#include "sim_core/collision/body_collider.h"
#include "sim_core/collision/skin_map_cache.h"
#include "sim_core/collision/superquadric.h"
#include "sim_core/collision/surface_geometry.h"

namespace costume::sim {

/// Options of the superquadric collider's construction.
struct SuperquadricColliderOptions {
  /// A segment with fewer skin vertices than this gets no superquadric [-] >= 11.
  int min_vertices_per_segment = 20;
  /// Spacing of the distance map's nodes [m] in [0.002, 0.2], on the box the segment's skin
  /// fills in the superquadric's frame (each side gets at least 2 intervals). 1 cm kept a
  /// skirt on the built-in humanoid's walk within 2 mm of the skin; 1.5 cm did not (2.3 mm).
  double map_spacing = 0.01;
  SuperquadricFitOptions fit;
  /// Where contact normals come from (see the file comment).
  enum class ContactNormal { kSuperquadricGradient, kSkin };
  ContactNormal contact_normal = ContactNormal::kSuperquadricGradient;
  /// Memory for drawings of the maps kept for reuse when a segment's skin comes back
  /// (skin_map_cache.h: a looping clip on the simulation's frame grid) [bytes]; 0 draws
  /// every map afresh. Reserved at construction, used as drawings are stored.
  std::size_t map_cache_bytes = std::size_t{256} << 20;
  /// A stored drawing is reused for a skin whose every corner, in the segment's frame, lies
  /// within this of the skin it was drawn from [m] in (0, 0.001].
  double map_cache_quantum = 1e-5;
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

/// The skin around one superquadric, sampled along rays from its centre. A ray is named by
/// the point where it leaves the superquadric's bounding box [−a1, a1]×[−a2, a2]×[−a3, a3]
/// (a cube map in the superquadric's frame scaled by 1/a): each of the six faces carries a
/// regular grid, about `map_spacing` apart, and nodes on shared edges and corners are shared.
/// Finding a point's place on the map costs three multiplications and two divisions, and
/// the nodes are spread evenly over the superquadric's sides whatever its exponents (the
/// paper's (eta, omega) grid crowds them onto the edges of the box-like shapes fitted to
/// limbs: with e1 = 0.1, three of its 33 rows span 80 % of a thigh).
struct SkinDistanceMap {
  /// Intervals along the box's x, y and z edges, and the nodes' spacing on the skin the
  /// grid was sized for [m].
  std::array<int, 3> intervals{2, 2, 2};
  double spacing = 0.01;
  /// Per face f (0 +x, 1 −x, 2 +y, 3 −y, 4 +z, 5 −z; face axis i = f/2 and the in-face axes
  /// j = (i+1)%3, k = (i+2)%3): the node at grid point (u, v), u along j, v along k, is
  /// face_nodes[f][u·(intervals[k] + 1) + v].
  std::array<std::vector<int>, 6> face_nodes;
  /// Per node: the ray's unit direction and the superquadric's radius along it [m]
  /// (constant: superquadric frame).
  std::vector<Eigen::Vector3d> ray;
  std::vector<double> surface_radius;
  /// Per node: the distance of its point on the box from the centre [m].
  std::vector<double> box_length;
  /// The box's half sizes: the superquadric's a1, a2, a3 [m].
  Eigen::Vector3d size = Eigen::Vector3d::Ones();
  /// Where each face's grid points start in a drawing's packed nodes (StoredMapNode, one
  /// per grid point of each face in turn, shared edge nodes repeated), and their number.
  std::array<int, 6> face_offset{};
  int num_face_points = 0;
  /// A cell whose nodes' radii, and their tangent planes' predictions on the ray, differ by
  /// more than this [m] straddles a silhouette seen from the centre and is read as its
  /// nearest skin, not blended.
  double silhouette_jump = 0.03;
  /// Node adjacency over the box's surface (compressed rows: the neighbours of node n are
  /// neighbours[neighbour_start[n] .. neighbour_start[n + 1])), for the filling.
  std::vector<int> neighbour_start;
  std::vector<int> neighbours;

  int num_nodes() const { return static_cast<int>(ray.size()); }
};

/// The skin a segment's map is drawn from: the triangles having a corner in the segment or
/// in one of its neighbours (SuperquadricCollider), and scratch for redrawing it without
/// allocating.
struct SegmentSkin {
  /// Avatar vertex indices of the triangles' corners, and the triangles as indices into it.
  std::vector<int> vertices;
  std::vector<Eigen::Vector3i> triangles;
  /// The corners (indices into `vertices`) of the skin the segment's shell is to hold: its
  /// own vertices and the triangles whose nearest centre seeing their outside is its own.
  /// Their farthest sets the reach.
  std::vector<int> held;
  /// Per triangle: the signed distances of its corners and edge midpoints from the body's
  /// other closed pieces in the rest pose, plus a tolerance [m] (< 0: inside one), and
  /// whether any is negative (where their quadratic interpolation is negative, the
  /// triangle is not skin).
  std::vector<std::array<double, 6>> burial;
  std::vector<char> partly_buried;
  /// Scratch of the last refresh: corners in the superquadric frame, scaled by 1/a, the
  /// face of the map's box each lies towards and its coordinates on it; per node the
  /// distance of the first exit (< 0: none) and the triangle that gave it.
  std::vector<Eigen::Vector3d> local;
  std::vector<Eigen::Vector3d> scaled;
  std::vector<char> face;
  std::vector<Eigen::Vector2d> face_point;
  /// Per triangle its outward unit normal at the last refresh (front-facing ones only).
  std::vector<Eigen::Vector3d> triangle_normal;
  /// Per triangle at the last refresh, found once for the drawing's passes: whether it can
  /// stop a ray within the reach, its normal (unnormalised) and plane (normal·corner: > 0
  /// seen from outside, an exit; < 0 an entry).
  std::vector<char> triangle_reached;
  std::vector<Eigen::Vector3d> triangle_side;
  std::vector<double> triangle_plane;
  /// Per corner its distance from the centre at the last refresh [m]; per triangle a bound
  /// on its longest edge [m] (the rest length with a margin for skinning's stretch).
  std::vector<double> distance;
  std::vector<double> edge;
  double longest_edge = 0.0;
  /// The triangles' adjacency and, after a skin check (SuperquadricCollider::SkinShell)
  /// since the last refresh, their normals for `corners`, a matrix copy of `local`.
  std::optional<SurfacePseudonormals> topology;
  Points corners;
  bool corners_current = false;
  /// Scratch of a skin check, per piece of `topology`: the nearest distance [m], triangle
  /// and point.
  std::vector<double> piece_distance;
  std::vector<int> piece_triangle;
  std::vector<TrianglePoint> piece_point;
  /// Scratch of a skin check's winding count along a ray (superquadric_collider.cc,
  /// CrossingsAlong): per crossed triangle the hit's distance [m] and +1 for an exit, −1
  /// for an entry, nearest first. Room for every triangle: never allocates.
  std::vector<std::pair<double, int>> ray_crossing;
  std::vector<double> hit_radius;
  std::vector<int> hit_triangle;
  /// Per node whether its hit is a folded ray's (below).
  std::vector<char> hit_folded;
  /// Per face grid point (duplicating shared nodes): the nearest hit in units of the
  /// point's distance from the centre (< 0: none) and its triangle.
  std::array<std::vector<double>, 6> face_hit;
  std::array<std::vector<int>, 6> face_triangle;
  /// The still layer (DrawExits in superquadric_map.cc): the first exits of the triangles
  /// whose corners have not moved in the segment's frame since `anchor` (where each corner
  /// was last seen to move), drawn once into `layer_hit` and `layer_triangle` (as
  /// face_hit, face_triangle) and copied in while they stay put, so that a drawing
  /// rasterises only the skin that skinning moves. Per corner whether it is in the layer;
  /// per triangle whether it is, and the role it played when the layer was drawn (0 stops
  /// no ray, 1 an exit, 2 an entry). Per corner, scratch of a drawing: whether it lay where
  /// it was anchored, and where it was before the drawing put it back there.
  std::vector<Eigen::Vector3d> anchor;
  std::vector<char> still;
  std::vector<char> resting;
  std::vector<Eigen::Vector3d> unsnapped;
  std::vector<char> in_layer;
  std::vector<char> layer_reached;
  std::array<std::vector<double>, 6> layer_hit;
  std::array<std::vector<int>, 6> layer_triangle;
  bool has_layer = false;
  /// Folded rays, which enter skin before their first exit (MarkFoldedRays in
  /// superquadric_collider.cc): per face grid point its slot (-1: none) and whether its
  /// hit moved past the first exit; per slot the face and grid point, the number of
  /// crossings met and the crossings (hit as in face_hit, triangle + 1, negated for an
  /// entry). Capacity fixed when the map is prepared: drawing never allocates.
  std::array<std::vector<int>, 6> face_slot;
  std::array<std::vector<char>, 6> face_folded;
  std::vector<std::pair<int, int>> folded_ray;
  std::vector<int> folded_count;
  std::vector<std::pair<double, int>> folded_crossing;
  int num_folded = 0;
  /// Per face the number of its folded rays, and, where there are any, their summed-area
  /// table over the face's grid ((nj + 2) × (nk + 2), entry (u + 1, v + 1) counting those
  /// at grid points up to (u, v)): a triangle whose grid box holds none crosses none of
  /// them. Capacity fixed when the map is prepared.
  std::array<int, 6> folded_on_face{};
  std::array<std::vector<int>, 6> folded_sum;
  /// The drawing, per node: the distance from the centre to the skin along the ray [m]
  /// (where the ray first leaves the skin the map holds, at most the segment's reach;
  /// minus SkinDistanceMap::surface_radius it is the paper's mapped distance), the skin's
  /// outward unit normal there (the ray at capped nodes) [-], and whether the node is
  /// capped: its ray met no skin within the segment's reach (it runs on inside the body,
  /// where the neighbours' shells hold the skin, or leaves through an open end), its radius
  /// the reach or filled from its neighbours; or its ray is folded and its exit is where
  /// the map's skin ends, which need not be the body's. Queries read the drawing packed
  /// (SuperquadricSegment::nodes).
  std::vector<double> radius;
  std::vector<Eigen::Vector3d> normal;
  std::vector<char> capped;
  /// Scratch of the filling: per node unknown / known / queued, and the queue.
  std::vector<char> state;
  std::vector<int> queue;
};

/// One segment as the collider sees it.
struct SuperquadricSegment {
  HAnimJoint segment = HAnimJoint::kHumanoidRoot;
  int joint = -1;
  /// A joint shell: a sphere centred on `joint` (the joint between `segment` and its
  /// nearest fitted ancestor) whose map holds both segments' skin near the joint, seen from
  /// the joint (docs/collision.md, "Bent joints"). Its contact normal is the skin's.
  bool joint_shell = false;
  Superquadric superquadric;  ///< frame relative to the joint's frame
  /// 1/a1, 1/a2, 1/a3 [1/m]: the map's scaling.
  Eigen::Vector3d inverse_size = Eigen::Vector3d::Ones();
  SkinDistanceMap map;
  SegmentSkin skin;
  /// The drawing the queries read, packed (SkinDistanceMap::face_offset): a stored drawing
  /// of the current skin (SkinMapCache), or `own_nodes` when the store had no room.
  const StoredMapNode* nodes = nullptr;
  std::vector<StoredMapNode> own_nodes;
  /// The step of the radii in `nodes` [m] (StoredMapNode::radius), from the rest reach.
  double radius_step = 1e-5;
  /// How far from the centre the map's rays may reach [m]: the farthest vertex of the skin
  /// the segment holds (SegmentSkin::held) in the last pose, and a margin; beyond, the
  /// neighbours' shells hold the skin.
  double reach = 0.0;
  /// Construction scratch: corners of the triangles whose nearest centre seeing their
  /// outside is this segment's.
  std::vector<int> viewed;
  /// Radius of a sphere about the superquadric's centre and a box in its frame holding the
  /// segment's shell (skin + the collider's thickness) at the last drawing of the map [m];
  /// while the map is stale, the reach and the box of the skin corners within it.
  double bounding_radius = 0.0;
  Eigen::AlignedBox3d shell_box;
  /// The box and the farthest radius of the skin at the last drawing of the map, in the
  /// superquadric's frame [m]: the shell's bounds without the thickness, as a stored drawing
  /// keeps them, so that it serves any thickness.
  Eigen::AlignedBox3d drawn_skin_box;
  double drawn_skin_farthest = 0.0;
  /// RMS radial distance of the skin vertices from the superquadric [m].
  double fit_rms = 0.0;
  /// How far the superquadric was moved from its fit so that its centre, where the map's
  /// rays start, lies inside the skin [m] (0 for most segments; MakeHuman's hands).
  double centre_shift = 0.0;
  int num_vertices = 0;
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
  /// The skin's outward unit normal (bilinear in the map, normalised), superquadric frame [-].
  Eigen::Vector3d skin_normal = Eigen::Vector3d::UnitZ();
  /// The reading came from capped map nodes (SkinDistanceMap::capped): `capped` when a
  /// blend includes one or a silhouette cell's nearest skin is one, `blind` when all four
  /// around the ray are (or that nearest one is) [-].
  bool capped = false;
  bool blind = false;
};

/// Probes the shell of `segment` at `q` (superquadric frame) [m]. Never throws or allocates.
void ProbeShell(const SuperquadricSegment& segment, const Eigen::Vector3d& q, double thickness,
                ShellProbe& probe);

class SuperquadricCollider : public BodyCollider {
 public:
  /// Fits the segments of `avatar` and draws their distance maps on the rest pose. The body
  /// starts in the rest pose. Throws InputError for a null avatar, bad settings or options.
  SuperquadricCollider(std::shared_ptr<const Avatar> avatar,
                       const BodyCollisionSettings& settings = {},
                       const SuperquadricColliderOptions& options = {});
  /// Segments point into the collider's own store of drawings: not copyable.
  SuperquadricCollider(const SuperquadricCollider&) = delete;
  SuperquadricCollider& operator=(const SuperquadricCollider&) = delete;

  /// See BodyCollider. `joint_world` has one frame per skeleton joint; a call with fewer
  /// frames, or a non-positive or non-finite dt after the first call, keeps the previous pose
  /// and sets the body's velocity to zero. `skinned_vertices` (one row per avatar vertex)
  /// are the skin the maps are redrawn from; with any other row count (none) the maps keep
  /// their last drawing and move rigidly with their segments. The maps are redrawn when a
  /// segment is first needed in the step (FindContacts or ProjectOut), so segments far from
  /// the cloth cost nothing. Never throws; allocates only on the first call with skin.
  void Update(const std::vector<Eigen::Isometry3d>& joint_world, const Points& skinned_vertices,
              double dt) override;

  /// See BodyCollider. The test is against the body's shell at the start of the step (the
  /// pose before the last Update) carrying the map of its end: a particle is in contact
  /// when its normal gap is within the margin (whatever its velocity: cloth resting on a
  /// swinging limb stays constrained), or its predicted gap gap + h·(v − v_body)·n is.
  /// The target normal velocity is ContactNormalVelocity's (contact.h) for the body surface's
  /// normal velocity v_body·n: a particle within the margin outside the shell keeps its own
  /// normal velocity, so a leaving one is not stopped and a resting one is not pulled in.
  /// One contact per particle: its most penetrating segment. Segments whose bounding sphere
  /// (grown by the motion of the step) misses the particles' bounding box are skipped;
  /// stats().num_tests counts the particle-segment pairs examined. Preconditions: h > 0,
  /// velocities the size of positions. Never throws; allocates only when `contacts` grows.
  void FindContacts(const Points& positions, const Points& velocities, double h, double margin,
                    std::vector<Contact>& contacts) override;

  /// See BodyCollider. Against the body at the end of the step (the last Update): a particle
  /// inside a segment's shell moves along that shell's normal onto it (a reading inside the
  /// skin checked against the skin's triangles, Penetration), and its velocity into the
  /// body (relative to the body's surface velocity) is removed; a few passes, for shells
  /// overlapping at joints. A particle still inside after them goes out of a closing crease
  /// (EscapePinch), or else midway between two opposed walls or back to the least deep
  /// place it went through (PlaceUnsettled). Returns the deepest normal penetration [m].
  /// Never throws or allocates.
  double ProjectOut(Points& positions, Points& velocities) override;
  double ProjectOut(Points& positions, Points& velocities,
                    std::span<const int> particles) override;
  /// See BodyCollider: the above for the listed particles, onto the skin.
  double ProjectOutOfSkin(Points& positions, Points& velocities,
                          std::span<const int> particles) override;

  BodyCollisionStats stats() const override { return stats_; }
  /// The avatar it was built for.
  const std::shared_ptr<const Avatar>& avatar() const { return avatar_; }
  void SetFriction(double friction) override { settings_.friction = friction; }
  /// See BodyCollider. Nothing is fitted or drawn again: a map holds the skin, and a stored
  /// drawing serves any thickness. Never allocates.
  void SetThickness(double thickness) override;

  /// Forgets where the body was, as a collider just built for the same avatar: the next
  /// Update sets the pose with zero velocity, and every map is redrawn or reused from the
  /// store before it is read. What the collider is built from stays: the fit, the maps'
  /// grids and the stored drawings, which are what a simulation built again for the same
  /// avatar keeps it for (ColliderMemo, sim_core/scene/body_colliders.h); the drawings only
  /// while they fill at most half the store's budget (else they are forgotten, so that the
  /// next motion can be stored: the store evicts nothing). Never throws or allocates.
  void Restart();

  /// Gives the store of drawings `bytes` (SuperquadricColliderOptions::map_cache_bytes),
  /// as a collider built with them: a new budget forgets every stored drawing, and each map
  /// is drawn again, or found in the new store, before it is read. The fit, the maps'
  /// grids and the pose stay. The old store's memory is given back before the new one is
  /// reserved; if that reservation throws (std::bad_alloc), the collider stores nothing.
  void SetMapMemory(std::size_t bytes);

  /// The segments that got a superquadric. Their maps are those of the last refresh (a
  /// segment not needed since the last Update keeps an older one).
  const std::vector<SuperquadricSegment>& segments() const { return segments_; }
  /// Redraws every segment's map that the last Update left stale (what FindContacts and
  /// ProjectOut do for the segments they need). Never throws or allocates.
  void RefreshAllMaps();
  /// The segments that had skin vertices but fewer than the minimum, so no superquadric:
  /// their vertices count as their nearest fitted H-Anim ancestor's.
  const std::vector<HAnimJoint>& skipped_segments() const { return skipped_; }
  /// A segment's superquadric frame in the world at the start / end of the coming step.
  const Eigen::Isometry3d& start_frame(int segment) const { return start_[segment].to_world; }
  const Eigen::Isometry3d& end_frame(int segment) const { return end_[segment].to_world; }
  /// The stored drawings' counters (SuperquadricColliderOptions::map_cache_bytes).
  const SkinMapCacheStats& map_cache_stats() const { return map_cache_.stats(); }

 private:
  /// The segments whose readings DeepestShell skipped inside their shells, the deepest
  /// reading first: each can speak only for the skin its own triangles hold (SkinShell).
  struct Undecided {
    static constexpr int kMax = 3;
    std::array<int, kMax> segment{};
    std::array<double, kMax> gap{};
    int count = 0;
    /// Keeps `s`, read `reading` [m] inside its shell, among the kMax deepest.
    void Add(int s, double reading);
  };
  /// A segment's superquadric frame in the world and its inverse.
  struct Placement {
    Eigen::Isometry3d to_world = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d to_local = Eigen::Isometry3d::Identity();
  };
  void SetPose(const std::vector<Eigen::Isometry3d>& joint_world, std::vector<Placement>& out);
  /// How far the shell of `segment` is grown for the body's motion when tested at the start
  /// of the step (`at_end` false: its sweep) or at its end (true: not at all) [m].
  double Motion(int segment, bool at_end) const;
  /// Keeps (active_) the segments whose bounding sphere, placed at the start or the end of
  /// the step and grown by Motion and `reach` [m], meets the box [lo, hi].
  void CullSegments(bool at_end, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                    double reach);
  /// Moves every segment's skin corners into its end-of-step frame and marks its map stale.
  void MoveSkin(const Points& skinned);
  /// Bounds segment `s`'s shell (reach, box, bounding radius) by the skin corners it holds
  /// and the thickness, until its map is redrawn, and marks the map stale.
  void BoundShell(int s);
  /// Brings the map of segment `s` up to its skin corners: a stored drawing of the same
  /// skin, or a new drawing (stored while the cache has room).
  void RefreshMap(int s);
  /// The deepest shell among the active segments at `x` (world), at the start or the end of
  /// the step: its normal gap [m], outward normal and surface velocity there. Shells farther
  /// than `reach` [m] plus Motion are skipped; so are blind readings inside a shell
  /// (ShellProbe) and any deeper than PlausibleDepth. Returns false when every shell was.
  /// `undecided` (when not null) gets the segments with the deepest skipped readings
  /// inside their shells; `shell` (when not null) the deepest shell's segment. Segments
  /// marked in excluded_ are not read.
  bool DeepestShell(const Eigen::Vector3d& x, bool at_end, double reach,
                    double& gap, Eigen::Vector3d& normal, Eigen::Vector3d& body_velocity,
                    Undecided* undecided = nullptr, int* shell = nullptr);
  /// Whether `x` (world) is more than kProjectionTolerance inside a shell
  /// at the end of the step, and if so its normal gap [m], outward normal and the body's
  /// velocity there: the deepest shell (DeepestShell), or, where only uncertain readings
  /// see it inside or they see it deeper than that shell, the skin triangles of the deepest
  /// of those that put it deeper still (SkinShell). A map reading `x` deeper than
  /// `checked_depth` [m] is checked against that segment's own triangles, which win where
  /// they put it shallower (CheckedShell).
  bool Penetration(const Eigen::Vector3d& x, double checked_depth, double& gap,
                   Eigen::Vector3d& normal, Eigen::Vector3d& body_velocity);
  /// DeepestShell at the end of the step (the `undecided` it fills), its reading kept only
  /// where it is no more than kProjectionTolerance inside or no deeper than
  /// `checked_depth` [m], or where the segment's own skin triangles (SkinShell) find `x`
  /// no shallower; where they find it shallower but inside, theirs; where outside, the
  /// next deepest shell's, checked the same way. Whether a shell is left that holds `x`
  /// inside.
  bool CheckedShell(const Eigen::Vector3d& x, double checked_depth, double& gap,
                    Eigen::Vector3d& normal, Eigen::Vector3d& body_velocity,
                    Undecided& undecided);
  /// Culls the segments against the box of `positions` at the end of the step (CullSegments).
  void CullSegmentsAtEnd(const Points& positions);
  /// ProjectParticleOut for each of `particles`, after culling the segments for all
  /// `positions`.
  double ProjectListedOut(Points& positions, Points& velocities, std::span<const int> particles,
                          double allowance);
  /// ProjectOut for particle `i`, onto the surface `allowance` [m] below the shell (0: the
  /// shell; the thickness: the skin): its normal penetration of that surface before the
  /// correction [m], 0 when it was outside.
  double ProjectParticleOut(Eigen::Index i, double allowance, Points& positions,
                            Points& velocities);
  /// Where ProjectParticleOut's passes left a particle still inside: the least deep place
  /// they went through and its depth [m], and the outward normals of the last two pushes.
  struct Unsettled {
    Eigen::Vector3d least_deep = Eigen::Vector3d::Zero();
    double least_depth = std::numeric_limits<double>::infinity();
    Eigen::Vector3d normal_before = Eigen::Vector3d::Zero();
    Eigen::Vector3d last_normal = Eigen::Vector3d::Zero();
  };
  /// Particle i after ProjectParticleOut's passes, still inside: out of a closing crease
  /// (EscapePinch), else midway between two opposed walls, back to the least deep place, or
  /// left, whichever is least deep.
  void PlaceUnsettled(Eigen::Index i, double allowance, const Unsettled& unsettled,
                      Points& positions, Points& velocities);
  /// A particle that ProjectOut's passes threw between two shells whose last outward
  /// normals `a` and `b` oppose (a crease closing on it) is moved from `from` (world) along
  /// the crease's opening, a + b, to the first place within kPinchEscapeSteps steps of
  /// kPinchEscapeStep that no shell holds. That place into `out`; false when the normals do
  /// not oppose, their sum has no clear direction or no step gets out.
  bool EscapePinch(const Eigen::Vector3d& from, const Eigen::Vector3d& a,
                   const Eigen::Vector3d& b, Eigen::Vector3d& out);
  /// The shell of `segment`'s skin triangles themselves (SegmentSkin) at the end of the
  /// step at `x` (world): its normal gap [m] (signed distance minus thickness), outward
  /// normal and the velocity of the segment's body there. A point its nearest skin puts
  /// outside but the winding number inside (skin skinned through skin, on a body of one
  /// piece) gets the nearest way out along a few rays instead (WoundExit in the .cc).
  /// Returns false when no triangle lies within kSkinCheckRadius of `x`.
  bool SkinShell(const Eigen::Vector3d& x, int segment, double& gap, Eigen::Vector3d& normal,
                 Eigen::Vector3d& body_velocity);
  /// How deep [m] a reading of `segment`'s map at `x` (world) is trusted: what the body
  /// travelled there within the step, plus the thickness and a node spacing for the map's
  /// own error.
  double PlausibleDepth(int segment, const Eigen::Vector3d& x, bool at_end) const;
  /// Velocity [m/s] of the body point of `segment` that is at `x` (world) at the start of
  /// the step (`at_end` false) or at its end (true), over the step's rigid motion.
  Eigen::Vector3d BodyVelocity(int segment, const Eigen::Vector3d& x, bool at_end) const;

  std::shared_ptr<const Avatar> avatar_;
  BodyCollisionSettings settings_;
  bool skin_normals_ = false;
  std::vector<SuperquadricSegment> segments_;
  std::vector<HAnimJoint> skipped_;
  std::vector<Placement> start_;
  std::vector<Placement> end_;
  /// Per segment: its map was not drawn from the skin of the last Update.
  std::vector<char> stale_;
  /// Per segment: not read by DeepestShell (CheckedShell's segments whose own skin found
  /// the point outside); all 0 between calls.
  std::vector<char> excluded_;
  /// start → end motion of each segment and its speed bound (translation of the centre plus
  /// bounding radius times rotation angle) [m].
  std::vector<Eigen::Isometry3d> motion_;
  std::vector<double> sweep_;
  double inverse_dt_ = 0.0;
  double step_ = 0.0;  ///< the last Update's dt while moving, else 0 [s]
  bool has_pose_ = false;
  /// The segments CullSegments kept, and per entry its centre in the placement culled
  /// [m] and bounding radius plus sweep [m] (tightened when its map is redrawn).
  std::vector<int> active_;
  std::vector<Eigen::Vector3d> active_centre_;
  std::vector<double> active_bound_;
  SkinMapCache map_cache_;
  BodyCollisionStats stats_;
};

}  // namespace costume::sim
