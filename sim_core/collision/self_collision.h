#pragma once
/// @file
/// Cloth–cloth (self) collision after Bridson, Fedkiw & Anderson 2002, "Robust treatment of
/// collisions, contact and friction for cloth animation" (§6 detection, §7.1–7.4 response),
/// run after the implicit solve on the step's straight-line path from the start-of-step
/// positions to the end-of-step positions. Broad phase: Bullet's btDbvt over the triangles'
/// boxes swept along that path, meeting the pairs within the thickness; its topology is
/// built once from the rest shape and only refitted afterwards. docs/collision.md
/// "## Self-collision" gives the pipeline and the places where it deviates from the paper.
/// A collision pass after the first examines only the pairs whose paths the one before
/// changed or found colliding: the others were examined on the same paths and found free.
///
/// Costs nothing when off: a scene without self-collision simply makes no SelfCollision.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"

struct btDbvt;      // Bullet's dynamic AABB tree; kept out of this header (Bullet is private).
struct btDbvtNode;

namespace costume::sim {

/// How self-collision is handled.
struct SelfCollisionSettings {
  /// Cloth thickness [m] > 0: the distance kept between parts of the cloth that share no
  /// particle (Bridson's h).
  double thickness = 0.004;
  /// Coulomb friction coefficient between touching parts of the cloth [-] >= 0, for
  /// particles `particle_friction` leaves to it.
  double friction = 0.3;
  /// Each particle's own (its fabric's) coefficient [-] >= 0, or < 0 for `friction`; empty:
  /// `friction` everywhere. Two touching parts rub with MixFriction of their sides' weighted
  /// coefficients (contact.h), so one fabric on itself keeps its own coefficient and silk on
  /// wool slides as it would on a body of wool's coefficient.
  std::vector<double> particle_friction;
  /// Repulsion spring stiffness [N/m] >= 0: a pair closer than the thickness by d is pushed
  /// apart by at most the impulse h·stiffness·d (Bridson §7.2), and never by more than would
  /// part that pair alone; 0 disables the push-out (only the approach is stopped).
  double stiffness = 1000.0;
  /// Passes of continuous collision detection with inelastic impulses (Bridson §7.3) before
  /// the impact-zone fallback [-] >= 0; also the number of Gauss-Seidel sweeps of the
  /// proximity stage.
  int max_iterations = 4;
};

/// Checks every field; throws InputError naming `context`.field, its value and range.
void ValidateSelfCollisionSettings(const SelfCollisionSettings& settings,
                                   const std::string& context);

/// What one Resolve did. Flags and counters instead of exceptions.
struct SelfCollisionReport {
  /// The call was refused (positions of the wrong size, h not finite and > 0, non-finite
  /// input, a hold naming no particle or with a non-finite normal) and left the state
  /// untouched. Remedy: the caller's bug or a rolled-back step.
  bool skipped = false;
  /// Primitive pairs (point–triangle and edge–edge sharing no particle) examined by the
  /// narrow phase, summed over the proximity stage and every collision pass.
  int pairs_tested = 0;
  /// Proximity pairs that received a repulsion / inelastic impulse (§7.2).
  int proximity_impulses = 0;
  /// Inelastic impulses for collisions found by continuous detection (§7.3).
  int collision_impulses = 0;
  /// Continuous-detection passes run (at most settings.max_iterations, plus the zone passes).
  int collision_passes = 0;
  /// Particles merged into impact zones that move without relative motion (the fallback).
  int zone_particles = 0;
  /// Collisions continuous detection still found after the last pass; 0 means the path from
  /// the start to the end positions crosses nothing. Remedy when > 0: a smaller step.
  int remaining_collisions = 0;
};

/// A particle the body holds in this step: self-collision may not move it further into the
/// body along `normal` (unit, out of the body) than the body's contact and correction left
/// it, as the body is an infinite mass behind it.
struct BodyHold {
  int particle = 0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
};

/// Resolves cloth–cloth contacts and collisions of one cloth model. Holds the broad-phase
/// tree and all scratch memory; not thread-safe; one instance per simulated cloth.
class SelfCollision {
 public:
  /// Builds the broad phase over `model`'s triangles at its rest positions. Throws
  /// InputError for bad settings (ValidateSelfCollisionSettings) or a triangle that repeats
  /// a particle.
  SelfCollision(std::shared_ptr<const ClothModel> model, const SelfCollisionSettings& settings);
  ~SelfCollision();
  SelfCollision(const SelfCollision&) = delete;
  SelfCollision& operator=(const SelfCollision&) = delete;

  /// Makes the step from `start_positions` (n×3) [m] to `state.positions` (n×3) [m]
  /// collision-free, for a step of length h [s] > 0. The path velocity v̄ = (end − start)/h
  /// is changed by the impulses and the end positions become start + h·v̄; `state.velocities`
  /// (n×3) [m/s] receive the same inelastic and friction impulses but not the push-out that
  /// restores the thickness (position only, so no energy is added; as in strain_limit.h).
  /// Pinned particles have infinite mass. `holds` (BodyHold) are the particles the body
  /// holds in this step: no impulse moves one of them further into the body, the body (of
  /// infinite mass) taking the push instead. Linear momentum is conserved by every impulse
  /// except what the holds take.
  /// Precondition for the guarantee: `start_positions` themselves cross nothing, except
  /// where the rest shape itself does (num_rest_tangled_triangles): pairs of those
  /// triangles are not examined, so the guarantee leaves them out.
  /// Never throws; allocation-free once its buffers have grown to the largest step's needs
  /// (they are reserved for a typical cloth at construction).
  SelfCollisionReport Resolve(const Points& start_positions, double h, ClothState& state,
                              const std::vector<BodyHold>& holds = {});

  /// Resolve for a short move after a step that Resolve has already made collision-free
  /// (the body's correction after it): the same, except that only pairs with a particle
  /// that moves along the path are examined, so pairs at rest, resolved by that call, are
  /// left as they are, and a move of a few particles costs a few tree walks instead of the
  /// whole cloth's. Particles the impulses set moving are examined in the later passes.
  SelfCollisionReport ResolveMove(const Points& start_positions, double h, ClothState& state,
                                  const std::vector<BodyHold>& holds = {});

  /// ResolveMove without the proximity stage: continuous detection and its impact zones
  /// only, so the move crosses nothing but may end with layers nearer than the thickness
  /// (the next Resolve parts them). For a correction that shortens springs, such as the
  /// strain limit after Resolve: the proximity stage's push-out would stretch them again.
  SelfCollisionReport ResolveCrossings(const Points& start_positions, double h,
                                       ClothState& state, const std::vector<BodyHold>& holds = {});

  const SelfCollisionSettings& settings() const { return settings_; }
  /// Triangles left out against each other because the rest shape passes through itself
  /// there (the pairs that cross at rest, with two rings of neighbours): a garment modelled
  /// that way cannot be kept on the side it started on, as it started on both.
  int num_rest_tangled_triangles() const;
  /// The cloth's unique edges (each particle pair of a triangle side once).
  const std::vector<std::pair<int, int>>& edges() const { return edges_; }

  /// One narrow-phase candidate: kind kPointTriangle (a = particle, b = triangle) or
  /// kEdgeEdge (a, b = edges).
  struct PrimitivePair {
    enum Kind : int { kPointTriangle = 0, kEdgeEdge = 1 };
    Kind kind = kPointTriangle;
    int a = 0;
    int b = 0;
  };

  /// Four particles with weights α_k such that Σ α_k x_k is the gap vector between a pair's
  /// closest points (point minus triangle point, or edge A point minus edge B point).
  /// Σ α_k = 0, so impulses α_k·I·n conserve momentum (Bridson §7.1).
  struct Stencil {
    int index[4] = {0, 0, 0, 0};
    double weight[4] = {0, 0, 0, 0};
  };

 private:
  /// Particles and edges of the mesh assigned to a triangle, so that each point–triangle and
  /// edge–edge pair is met exactly once per overlapping triangle pair.
  struct Owned {
    int vertices[3] = {0, 0, 0};
    int num_vertices = 0;
    int edges[3] = {0, 0, 0};
    int num_edges = 0;
  };

  /// A pair within reach of the thickness: closest points and normal at the step's start.
  struct NearPair {
    Stencil stencil;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
    double distance = 0.0;
    /// Σ α_k²/m_k [1/kg] (> 0: pairs of four pinned particles are dropped).
    double inverse_mass = 0.0;
    /// Coulomb coefficient of the pair [-] (PairFriction).
    double friction = 0.0;
    /// Bounds and accumulated values of the pair's normal impulses [N·s] on the path and
    /// on the state velocities (projected Gauss-Seidel).
    double max_impulse = 0.0;
    double path_impulse = 0.0;
    double state_impulse = 0.0;
  };

  /// Construction: which triangle owns each particle and edge (Owned), the tree over the
  /// rest shape with its refit order, the per-step scratch.
  void AssignOwnership();
  void BuildTree();
  void ReserveScratch();
  /// Marks the triangles of the pairs that pass through each other in the rest shape, and
  /// their neighbours (triangle_tangled_): pairs of two such triangles are left alone.
  void FindRestTangles();
  /// The particles of the triangle pairs that pass through each other in the rest shape.
  std::vector<char> ParticlesOfRestCrossings();
  /// Which pairs a ResolvePath examines, and whether it keeps them the thickness apart.
  enum class PathMode {
    kWhole,            ///< Resolve: every pair
    kMoving,           ///< ResolveMove: the pairs with a moving particle
    kMovingCrossings,  ///< ResolveCrossings: those, without the proximity stage
  };
  SelfCollisionReport ResolvePath(const Points& start_positions, double h, ClothState& state,
                                  const std::vector<BodyHold>& holds, PathMode mode);
  void Refit(const Points& start, double h, double margin);
  /// Which primitive pairs a collection gathers.
  enum class Candidates {
    /// Every pair whose boxes come within the margin.
    kAll,
    /// Only such pairs with a particle flagged in particle_changed_.
    kChanged,
    /// kChanged's, and the last collection's pairs without a flagged particle that still
    /// come within the margin (the last collection's margin being at least as large).
    kKeptAndChanged,
  };
  /// The overlapping leaves of the refitted tree: all of them (kAll), or those with a
  /// triangle that has a flagged particle.
  void CollectTrianglePairs(Candidates candidates);
  void CollectPairs(double margin, Candidates candidates);
  bool Overlaps(const PrimitivePair& pair, double margin) const;
  /// Whether a particle of the pair is flagged in particle_changed_.
  bool Changed(const PrimitivePair& pair) const;
  /// The collected pairs are examined on the current path: remembers it and clears the flags.
  void StartExamining();
  /// Flags the particles whose path velocity differs from the one last examined.
  void FlagChangedPaths();
  void ProximityStage(const Points& start, double h, ClothState& state,
                      SelfCollisionReport& report);
  bool Repel(NearPair& near, double h, ClothState& state);
  /// Keeps hold `index` from moving into the body (one projected Gauss-Seidel visit).
  bool Hold(int index, ClothState& state);
  /// The pair's inverse masses `inverse[4]` [1/kg] for an impulse along +n, held particles
  /// it would push into the body counting as infinitely heavy.
  void HeldMasses(const Stencil& s, const Eigen::Vector3d& n, double inverse[4]) const;
  /// The relative normal velocity change [m/s] that ends a pair the thickness (and two
  /// tolerances) apart from `distance` [m] at the start, given its `approach` [m/s].
  double FullParting(double approach, double distance, double h) const;
  double PairFriction(const Stencil& stencil) const;
  int CollisionPass(const Points& start, double h, ClothState& state, bool merge_zones,
                    Candidates candidates, SelfCollisionReport& report);
  void ImpactZones(const Points& start, double h, ClothState& state, Candidates candidates,
                   SelfCollisionReport& report);

  std::shared_ptr<const ClothModel> model_;
  SelfCollisionSettings settings_;
  Eigen::VectorXd inverse_mass_;
  std::vector<std::pair<int, int>> edges_;
  std::vector<Owned> owned_;
  std::unique_ptr<btDbvt> tree_;
  struct TreeStack;
  std::unique_ptr<TreeStack> tree_stack_;
  /// Particles whose path changed since their pairs were last examined, or that met a
  /// collision there (only their pairs can meet anything new), their triangles, and the
  /// path velocities last examined [m/s].
  std::vector<char> particle_changed_;
  std::vector<char> triangle_changed_;
  Points path_examined_;
  std::vector<char> triangle_tangled_;
  /// One leaf per triangle, and the internal nodes children first (the refit order).
  std::vector<btDbvtNode*> leaves_;
  std::vector<btDbvtNode*> internal_nodes_;
  // Scratch, sized once.
  std::vector<std::pair<int, int>> triangle_pairs_;
  std::vector<PrimitivePair> pairs_;
  std::vector<NearPair> proximities_;
  /// This step's body holds, their path and state velocities along the normal at the start of
  /// Resolve, and their accumulated outward velocity changes (projected Gauss-Seidel).
  const std::vector<BodyHold>* holds_ = nullptr;
  std::vector<int> hold_of_;
  std::vector<double> hold_path_start_, hold_state_start_, hold_path_push_, hold_state_push_;
  /// Boxes swept over the step (corners, one row per particle, edge, triangle) [m].
  Points box_lo_, box_hi_, edge_lo_, edge_hi_, triangle_lo_, triangle_hi_;
  Points path_velocity_;
  std::vector<int> zone_parent_;
  std::vector<int> zone_size_;
  Eigen::VectorXd zone_mass_;
  Points zone_momentum_, zone_state_momentum_;
};

/// Counts the cloth edges (each unique triangle side once) that pass through a triangle of
/// the same cloth sharing none of its particles, at `positions` (n×3) [m]: the test oracle
/// for self-intersection. Brute force over all edge–triangle pairs with orientation
/// (signed-volume) tests: an edge counts when its ends lie strictly on opposite sides of the
/// triangle's plane (off it by more than 1e-12 of the tests' largest term, so that rounding
/// does not decide) and the line through it passes strictly inside the triangle; touching
/// and coplanar configurations do not count. Only pairs whose boxes overlap are tested (a
/// Bullet tree over the triangles), which changes no answer. For tests, tools and the
/// per-frame measures of a run (garment_metrics.h); allocates.
int CountCrossingEdges(const ClothModel& model, const Points& positions);

}  // namespace costume::sim
