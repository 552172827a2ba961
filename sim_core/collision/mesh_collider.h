#pragma once
/// @file
/// The paper's accurate avatar collision (§4): cloth particles against the skinned avatar
/// mesh. The mesh is split into regions of about N×N triangles grown over triangle
/// adjacency; neighbouring regions whose normals fit in a flatness cone (Provot 1997's
/// normal-cone test) are merged level by level, up to four at a time (quadtree-like), so
/// flat parts of the body are covered by few large regions. A Bullet btDbvt per connected
/// piece of the body over its region boxes, refitted every frame, is the broad phase.
/// Inside a region the triangles are found through a grid over the region's mean plane:
/// the region is tested as the height field a flat region is, which is what makes a large
/// flat region cheap. Contacts follow Bridson, Fedkiw & Anderson 2002: proximity within the
/// cloth's thickness, resolved as velocity constraints in the implicit solve.
///
/// The narrow phase looks for each piece's nearest triangle nearest first: the particle's
/// last nearest triangle starts the search radius, regions are taken nearest box first,
/// and the radius shrinks to the best distance found, so that the boxes of the region,
/// grid cells and triangles rule out all but a few triangles. Per particle and piece it
/// remembers that triangle and bounds on the distance, which the particle's and the
/// piece's motion since can only shrink by as much: a piece that cannot have come near
/// enough to matter is not searched at all (MeshCollisionOptions::reuse_bounds).
///
/// Skinning can move skin through other skin (a kicking thigh through the groin): there
/// the nearest triangle may be buried skin seen from its outer side while the particle is
/// inside the skin that buried it. ProjectOut therefore counts the winding number (a ray's
/// signed crossings, through the same region trees) of particles near the skin that their
/// nearest triangle puts outside (MeshCollisionOptions::find_buried), and of particles that
/// had skin within reach when FindContacts ran and have none now: a limb swept over them
/// faster than the proximity search reaches.
///
/// Deviation from the paper: the paper tests a flat region "coarsely" without saying how;
/// here it is the slab and plane grid above, which is exact (no contact is lost, whatever
/// the region's shape), flatness only making it effective.
///
/// The cloth has adaptive regions too (cloth_regions.h, after SetCloth): a flat piece of
/// cloth makes one broad-phase query against the body's region tree for all its
/// particles instead of one per particle; each particle then tests only the body regions
/// that query returned. Contacts are the same with or without them.

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/cloth/cloth_model.h"
#include "sim_core/collision/body_collider.h"
#include "sim_core/collision/cloth_regions.h"
#include "sim_core/collision/surface_geometry.h"

namespace costume::sim {

/// Position-correction passes per particle in MeshCollider::ProjectOut: in a crease between
/// two pieces (the back of a bent knee) moving a particle out of one can move it into the
/// other, so it is corrected again against the piece it is then deepest in. Two passes took
/// the kicking skirt from 9.8 mm to under 1 mm inside the skin (docs/collision.md); four
/// left it at 0 mm but with twice the strain, the cloth in the crease thrown through it.
/// Where the second skin faces the first (a pinch narrower than two shells, as at an
/// armpit), the second pass puts the particle midway instead (docs/collision.md, "Pinches").
inline constexpr int kMeshProjectionPasses = 2;

// Internal (mesh_collider.cc): one region, and all regions with their grids and Bullet tree.
struct MeshColliderRegion;
struct MeshColliderRegions;

/// Options of the mesh method's regions.
struct MeshCollisionOptions {
  /// Base regions hold about region_size × region_size triangles [-], 1 ..= 256 (8 → 64).
  int region_size = 8;
  /// Merge flat neighbouring regions (the paper's adaptive regions); false keeps the base
  /// regions, so the saving can be measured.
  bool adaptive = true;
  /// Flatness cone [rad], in [0, π/2): regions merge only while every triangle normal of
  /// the union lies within this angle of the union's area-weighted mean normal.
  double flatness_angle = 0.35;
  /// Merge levels at most [-], 0 ..= 16; each level joins a region with up to three of
  /// its neighbours.
  int max_merge_levels = 8;
  /// Penetration below the surface [m] > 0 that FindContacts and ProjectOut still see;
  /// particles deeper than this are lost, as with any proximity method.
  double max_penetration = 0.05;
  /// Remember per particle what its last search learnt (its nearest triangle per piece and
  /// bounds on the distances), so that a piece which the particle's and the body's motion
  /// since cannot have brought near enough to matter is not searched again. Contacts and
  /// corrections are those of a full search, up to which of equally near triangles is
  /// kept, wherever each piece of the body is closed and does not intersect itself (the
  /// bounds rely on its signed distance being 1-Lipschitz); false searches every piece
  /// within reach every time.
  bool reuse_bounds = true;
  /// Query the body per cloth region rather than per particle (once SetCloth has given the
  /// cloth's topology); false reproduces the per-particle queries exactly. It takes about
  /// half the counted tests and 2–15 % less time on a flat or folded sheet
  /// (tools/collision_regions_bench, docs/collision.md). Off by default: the scene does not
  /// give the collider its cloth, and with the particles' memory most body pieces are not
  /// walked at all, leaving less broad phase to save.
  bool cloth_regions = false;
  /// Count, in ProjectOut, the winding number of each particle whose nearest triangle puts
  /// it outside within max_penetration, and move it out when it is inside: where skinning
  /// moves skin through other skin (MakeHuman's thigh through its groin in a kick), the
  /// nearest triangle can be buried skin seen from its outer side while the particle is
  /// inside the skin that buried it (docs/collision.md, "Buried skin"). Likewise a
  /// particle FindContacts found within reach of a piece's skin and ProjectOut finds none
  /// of it within reach: the step took it more than max_penetration deep, where no
  /// proximity search sees it ("Lost particles"). Only in closed pieces (an open one has
  /// no inside); false leaves such particles where they are.
  bool find_buried = true;
  /// Refit a body region (its plane frame, grid and packed triangles) only when a query
  /// first reaches it after Update, so that skin no cloth comes near (the arms and head
  /// under a skirt) costs no refit; until then its tree box is the box it was last fitted
  /// in, grown by how far its vertices have moved since, so no query misses it. Contacts
  /// and corrections are those of refitting every region in Update (false), up to which of
  /// equally near triangles is kept.
  bool lazy_refit = true;
  /// Cloth base regions hold about cloth_region_size × cloth_region_size particles [-],
  /// 1 ..= 256.
  int cloth_region_size = 8;
  /// Take flat nodes of the cloth's hierarchy whole (the adaptive regions); false queries
  /// every base region and skips the normal cones, so the saving can be measured.
  bool cloth_adaptive = true;
  /// Cloth flatness cone [rad], in [0, π/2): a node of the cloth's hierarchy whose
  /// triangle normals all lie within this angle of its axis is queried as one region.
  double cloth_flatness_angle = 0.35;
  /// The cloth's normal cones are refreshed for one base region in every
  /// cloth_cone_period per FindContacts call, in turns [-], 1 ..= 64: they only choose
  /// how coarsely to query (contacts are the same whatever they say), and one cone per
  /// cloth triangle every call costs more than taking flat cloth whole saves.
  int cloth_cone_period = 4;
};

/// Cloth against the avatar's skinned mesh. Works for open meshes too, but inside and
/// outside are only meaningful where the skin is closed; a body made of several closed
/// pieces is their union (a particle's contact is with the piece it penetrates most).
class MeshCollider : public BodyCollider {
 public:
  /// Builds regions and broad phase on the avatar's rest pose. Throws InputError naming
  /// the avatar, the field and its allowed range for: an avatar without triangles, a
  /// negative or non-finite thickness or friction, an option out of its range above.
  MeshCollider(std::shared_ptr<const Avatar> avatar, const BodyCollisionSettings& settings,
               const MeshCollisionOptions& options = {});
  ~MeshCollider() override;
  MeshCollider(const MeshCollider&) = delete;
  MeshCollider& operator=(const MeshCollider&) = delete;

  /// Gives the cloth's topology (ClothModel::triangles, lattice shape; positions are
  /// passed to FindContacts) and builds its region hierarchy, used when
  /// options.cloth_regions is set and FindContacts gets cloth.num_particles() positions.
  /// Without it, or for any other particle count, FindContacts queries per particle.
  /// Allocates all FindContacts scratch. Throws nothing beyond std::bad_alloc (the options
  /// were checked by the constructor).
  void SetCloth(const ClothModel& cloth);

  /// Takes the skinned vertices (num_vertices×3) [m] (the joint frames are not needed);
  /// vertex velocities are (new − previous)/dt. Refits the region boxes and grids, or, with
  /// options.lazy_refit, grows their tree boxes by their vertices' motion. Ignored
  /// when the row count is wrong; a non-positive dt gives zero velocities. Never throws;
  /// never allocates.
  void Update(const std::vector<Eigen::Isometry3d>& joint_world, const Points& skinned_vertices,
              double dt) override;

  /// See BodyCollider. Normal: unit direction from the closest surface point to the
  /// particle (its opposite inside), the closest feature's pseudonormal when on the
  /// surface. Target normal velocity: the surface velocity at the closest point along the
  /// normal plus (thickness − signed distance)/h. Contacts are appended in particle order.
  /// Never throws; allocates only through `contacts` growing (and, without SetCloth, on
  /// its first call or when the particle count changes: the particles' memory).
  void FindContacts(const Points& positions, const Points& velocities, double h, double margin,
                    std::vector<Contact>& contacts) override;

  /// See BodyCollider: moves particles inside the shell along the normal onto it and
  /// removes their velocity into the body relative to the surface's. With
  /// options.find_buried, a particle its nearest triangle puts outside, within
  /// max_penetration, but inside by the winding number (skin skinned through skin) goes out
  /// where the winding number first falls to 0 along the nearest of 14 rays, onto the
  /// shell (exits up to kLostParticleSearch away in the nearest triangle's piece, folded
  /// through itself there, max_penetration in others); so does one that FindContacts
  /// found within reach of a piece and that is now deeper in it than max_penetration
  /// (exits up to kLostParticleSearch away). Returns the deepest penetration of the shell
  /// before the correction [m]. Uses (and updates) the particles' memory when
  /// FindContacts last had as many particles.
  /// Never throws; never allocates.
  double ProjectOut(Points& positions, Points& velocities) override;
  double ProjectOut(Points& positions, Points& velocities,
                    std::span<const int> particles) override;
  /// See BodyCollider: the above for the listed particles, onto the skin (a buried or lost
  /// particle's exit, which ProjectOut finds, still onto the shell).
  double ProjectOutOfSkin(Points& positions, Points& velocities,
                          std::span<const int> particles) override;

  BodyCollisionStats stats() const override { return stats_; }
  void SetFriction(double friction) override { settings_.friction = friction; }
  /// See BodyCollider. The regions' boxes are fattened by the thickness at every Update, and
  /// the queries add it as they search: nothing else holds it.
  void SetThickness(double thickness) override { settings_.thickness = thickness; }

  /// Regions after merging, and before it (the base regions of about N×N triangles).
  int num_regions() const;
  int num_base_regions() const { return num_base_regions_; }
  /// Regions not fitted to the current pose (MeshCollisionOptions::lazy_refit): no query
  /// has reached them since the body last moved them.
  int num_stale_regions() const;

  /// The cloth's region hierarchy after SetCloth, else null.
  const ClothRegions* cloth_regions() const { return cloth_.get(); }
  /// Broad-phase queries of the body's region tree in the last FindContacts call: one per
  /// cloth region taken (with cloth regions) or per particle (without).
  long long num_broad_phase_queries() const { return num_queries_; }

 private:
  /// The closest surface point to `point` over the pieces within `reach` [m] of it.
  struct Nearest {
    bool found = false;
    double signed_distance = 0.0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
    Eigen::Vector3d surface_velocity = Eigen::Vector3d::Zero();
    /// The nearest surface point [m].
    Eigen::Vector3d closest = Eigen::Vector3d::Zero();
    /// The piece of the nearest surface point (−1 when none was found).
    int piece = -1;
  };
  /// Where a query's body regions come from: the per-piece region trees, or candidate
  /// slots [first, first + count) gathered for a cloth region.
  struct Source {
    bool from_list = false;
    int first = 0;
    int count = 0;
  };
  /// What a particle's last search learnt about one piece of the body: its nearest
  /// triangle (−1: none yet) and lower bounds on its signed and unsigned distance [m] at
  /// the particle's anchor, each plus the piece's travel then [m]. −inf: unknown.
  struct PieceMemory {
    int triangle = -1;
    double signed_bound = -std::numeric_limits<double>::infinity();
    double distance_bound = -std::numeric_limits<double>::infinity();
  };
  /// A ray's crossing of a triangle: distance along the ray [m], packed slot, +1 leaving
  /// the skin, −1 entering it.
  struct RayExit {
    double distance = 0.0;
    int slot = -1;
    int sign = 0;
  };
  static constexpr int kMaxExitCrossings = 32;
  /// How far a lost particle's exit is looked for [m]: through any limb or torso.
  static constexpr double kLostParticleSearch = 0.3;
  /// Bodies of more pieces search without memory (it would cost pieces × particles).
  static constexpr int kMaxRememberedPieces = 64;

  /// The nearest surface point to `point` within `reach` [m], exact whenever it matters:
  /// when its signed distance is at most `threshold` + h × its piece's fastest vertex speed
  /// [m]. Otherwise the answer may be another piece's or none, also above its threshold.
  /// `particle` >= 0 uses and updates that particle's memory (see memory_).
  Nearest Query(const Eigen::Vector3d& point, double reach, double threshold, double h,
                int particle, const Source& source);
  /// The searched piece within reach with the lowest signed distance, −1 for none.
  int Winner() const;
  /// Lists the regions of `piece` within `radius` [m] of `point`; returns how many.
  int Collect(const Eigen::Vector3d& point, int piece, double radius, const Source& source);
  /// Searches the `count` listed regions nearest box first, the piece's radius shrinking
  /// to the distance of its nearest triangle found so far.
  void SearchCandidates(const Eigen::Vector3d& point, int count);
  /// Gathers the body regions whose boxes overlap [box_min, box_max] into candidate slots
  /// [0, count), piece by piece in tree order; returns the count.
  int GatherCandidates(const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max);
  /// How far a particle's search must reach [m]; +inf or NaN for bad input.
  double ReachOf(const Eigen::Vector3d& velocity, double h, double margin) const;
  /// The signed distance above which FindContacts makes no contact for a particle moving
  /// at `velocity` with a piece at rest [m] (Query adds h × the piece's speed).
  double ContactThreshold(const Eigen::Vector3d& velocity, double h, double margin) const;
  /// The contact rule: fills `contact` and returns true when the particle needs one.
  bool MakeContact(int particle, const Eigen::Vector3d& velocity, const Nearest& nearest,
                   double h, double margin, Contact& contact) const;
  void FindContactsPerParticle(const Points& positions, const Points& velocities, double h,
                               double margin, std::vector<Contact>& contacts);
  void FindContactsPerRegion(const Points& positions, const Points& velocities, double h,
                             double margin, std::vector<Contact>& contacts);
  /// Tests the particles of cloth node k against candidate slots [first, first + count),
  /// narrowing the list for each child on the way down to the base regions.
  void TestClothNode(int k, int first, int count, const Points& positions,
                     const Points& velocities, double h, double margin);
  /// Starts searching `piece` within radius² `radius_squared` [m²].
  void ActivatePiece(int piece, double radius_squared);
  /// Takes `triangle` as its piece's nearest so far when within the piece's radius.
  void TryTriangle(int triangle, const Eigen::Vector3d& point);
  /// Keeps, for the region's piece, its nearest triangle within the piece's radius.
  void SearchRegion(const MeshColliderRegion& region, const Eigen::Vector3d& point);
  void SearchCell(const MeshColliderRegion& region, int cell, const Eigen::Vector3d& point);
  /// The signed distance [m] of the piece's nearest triangle (+inf for none), and whether
  /// it lies within `reach` [m].
  void ResolvePiece(int piece, const Eigen::Vector3d& point, double reach);
  /// The answer from the resolved pieces; resets the per-piece scratch.
  Nearest Finish(const Eigen::Vector3d& point);
  /// Remembers for `particle` what this query learnt at `point`, `slack` [m] from its
  /// anchor.
  void Remember(PieceMemory* memory, int particle, const Eigen::Vector3d& point,
                double slack);
  /// Makes the particle memory n particles long (allocates when n changes).
  void SizeMemory(Eigen::Index n);
  bool UsesMemory() const;
  /// `particle`, the index of its memory, or −1 when the body goes without memory.
  int MemoryOf(int particle) const;
  /// Adds how far each piece, and each region, moves to `skinned_vertices` to the travels.
  void AddTravel(const Points& skinned_vertices);
  /// Updates the pseudonormals and refits every region (`all`), or marks each region whose
  /// vertices moved stale, to be fitted when a query reaches it, and grows its tree box by
  /// how far they moved since its last fit (MeshColliderRegion::travel, from AddTravel).
  void Refit(bool all);
  /// The skin's velocity [m/s] at barycentric `weights` of `triangle`.
  Eigen::Vector3d SurfaceVelocity(int triangle, const Eigen::Vector3d& weights) const;
  /// Moves particle i out of the skin when it is inside by the winding number though its
  /// nearest triangle (of piece `folded`; `outward` [-] points away from it) puts it
  /// outside: exits up to kLostParticleSearch away in `folded`, max_penetration in other
  /// pieces. Returns the depth [m] it had below the shell (0 when it was not inside).
  double ProjectOutBuried(Eigen::Index i, const Eigen::Vector3d& outward, int folded,
                          Points& positions, Points& velocities);
  /// Moves particle i out of closed `piece` when it is inside it by the winding number
  /// (the first ray along `outward` [-]): onto the shell beyond the nearest of 14 rays'
  /// exits within `max_depth` [m] whose shell point is outside. Returns the depth below
  /// the shell it had [m], 0 when it was not inside or no exit would do.
  double ProjectOutOfPiece(Eigen::Index i, int piece, const Eigen::Vector3d& outward,
                           double max_depth, Points& positions, Points& velocities);
  /// ProjectParticleOut for each of `particles`, onto `shell` [m] above the skin.
  double ProjectListedOut(Points& positions, Points& velocities, std::span<const int> particles,
                          double shell);
  /// What every particle's correction in one ProjectOut shares.
  struct Correction {
    double shell = 0.0;  // how far off the skin particles go [m]: the thickness, or 0
    double reach = 0.0;  // the thickness plus max_penetration [m]
    bool remembered = false;  // FindContacts left its memory for these particles
    bool near_known = false;  // and near_piece_ for them
  };
  Correction CorrectionFor(const Points& positions, double shell) const;
  /// ProjectOut for particle `i`, onto `how.shell`: its depth below that before the
  /// correction [m], 0 when it was outside.
  double ProjectParticleOut(Eigen::Index i, const Correction& how, Points& positions,
                            Points& velocities);
  /// Particle i had skin of piece near_piece_[i] within reach when FindContacts ran, and
  /// none now: when it is inside that piece, out along the nearest exit within
  /// kLostParticleSearch (ProjectOutOfPiece). Returns its depth below the shell [m].
  double ProjectOutLost(Eigen::Index i, Points& positions, Points& velocities);
  /// The piece a FindContacts query puts within ProjectOut's reach of the particle, −1
  /// for none.
  int NearPiece(const Nearest& nearest) const {
    return nearest.found && std::abs(nearest.signed_distance) <=
                                settings_.thickness + options_.max_penetration
               ? nearest.piece
               : -1;
  }
  /// Whether the last query searched `piece` and found no triangle of it within reach.
  bool SearchedBeyondReach(int piece) const;
  /// Whether `point` is inside `piece` by its winding number: the signed crossings of a
  /// ray from it, first along `direction`, another where that one grazes an edge.
  bool InsidePiece(int piece, const Eigen::Vector3d& point, const Eigen::Vector3d& direction);
  /// The signed crossings (exits − entries) of the ray from `point` along `direction`
  /// with `piece`; false when it passes too near an edge or a plane to count.
  bool WindingInPiece(int piece, const Eigen::Vector3d& point, const Eigen::Vector3d& direction,
                      int& winding);
  /// Where a ray from `point` along the unit `direction` first reaches winding number 0 in
  /// `piece`: the distance [m] to that crossing and its packed slot. False when the ray
  /// passes too near an edge, crosses more than kMaxExitCrossings triangles or never gets
  /// out.
  bool ExitAlong(int piece, const Eigen::Vector3d& point, const Eigen::Vector3d& direction,
                 RayExit& exit);

  std::shared_ptr<const Avatar> avatar_;
  BodyCollisionSettings settings_;
  MeshCollisionOptions options_;
  SurfacePseudonormals normals_;
  Points vertices_;
  Points vertex_velocities_;
  double max_vertex_speed_ = 0.0;
  bool has_pose_ = false;
  int num_base_regions_ = 0;
  std::unique_ptr<MeshColliderRegions> regions_;
  BodyCollisionStats stats_;
  long long num_tests_ = 0;  // tests of the current query, summed into stats_
  long long num_queries_ = 0;
  /// Cloth side (SetCloth): hierarchy, per-particle query half sizes [m] (−1: skipped)
  /// and reaches [m], and per-particle contact slots so contacts come out in order.
  std::unique_ptr<ClothRegions> cloth_;
  std::vector<double> half_extents_;
  std::vector<double> reaches_;
  std::vector<Contact> particle_contacts_;
  std::vector<char> has_contact_;
  /// Per particle, the piece FindContacts found within ProjectOut's reach (NearPiece).
  std::vector<int> near_piece_;
  /// Per particle and piece, what the particle's last query learnt (PieceMemory), and
  /// where the particle was then (its anchor). Bounds shrink by the particle's and the
  /// piece's motion since; a piece whose bound shows it cannot matter is not searched.
  /// Empty when the body has more than kMaxRememberedPieces pieces.
  std::vector<PieceMemory> memory_;
  Points anchors_;
  /// How far each piece's vertices have moved in all Updates, summed [m]; +inf after a
  /// non-finite pose.
  std::vector<double> piece_travel_;
  std::vector<double> piece_speed_;  // fastest vertex of each piece [m/s]
  std::vector<double> piece_step_;   // Update scratch: per piece, then per vertex [m², m²]
  std::vector<double> vertex_step_;
  /// Pieces that are closed (every edge shared by two triangles): only their signed
  /// distance is 1-Lipschitz, which the bounds rely on, and only they have a winding number.
  std::vector<char> piece_closed_;
};

}  // namespace costume::sim
