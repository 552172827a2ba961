#pragma once
/// @file
/// What a scene file describes, as plain data (docs/scene_format.md). The assets layer
/// parses files into this; BuildSimulation (simulation.h) turns it into a running engine,
/// building only what the scene enables.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/avatar_motion.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/cloth/material.h"
#include "sim_core/cloth/mesh_cloth.h"
#include "sim_core/solver/solver_method.h"

namespace costume::sim {

/// The tightest PCG tolerance a scene may ask for. Below it double precision cannot bring
/// the residual down (the rounding of one product is about 1e-16 of it), so every step would
/// run to max_iterations (1e-300: 68 ms a frame on the garment scene in one run).
constexpr double kMinSolverTolerance = 1e-12;

/// solver.threads for "as many as the machine has".
constexpr int kMachineThreads = 0;

struct SolverSettings {
  SolverMethod method = SolverMethod::kPcg;
  /// PCG stops when the preconditioned residual falls below tolerance² times that of the
  /// right-hand side (B&W's criterion) [-], in [kMinSolverTolerance, 1).
  double tolerance = 1e-2;
  /// PCG iteration cap per step, >= 1.
  int max_iterations = 1000;
  /// Pyramid levels the hierarchical and multigrid solvers use, counting level 0; 0 means
  /// as many as the lattice allows. 1 is the flat solver.
  int levels = 0;
  /// The multigrid solver's coarse-level matrices: Galerkin products PᵀAP of level 0's
  /// matrix or the coarse models rediscretised at the restricted state.
  CoarseOperator coarse_operator = CoarseOperator::kRediscretised;
  /// Implicit steps per frame, >= 1; the step is 1/(frame_rate·substeps).
  int substeps = 1;
  /// Largest strain structural and shear springs keep after a step [-], in [0, 10]; 0
  /// switches strain limiting off (strain_limit.h: Provot 1995).
  double strain_limit = 0.1;
  /// Threads the solver's loops run on, in [0, ThreadPool::kMaxThreads]; kMachineThreads
  /// (0): the machine's. Any count gives the same bits (thread_pool.h).
  int threads = kMachineThreads;
};

/// Which optional effects the scene switches on. Off costs nothing: the engine does not
/// build what is off.
struct Effects {
  bool air_drag = true;
  bool friction = true;
  bool self_collision = false;
};

/// A garment: one lattice panel, one mesh, a built-in pattern sewn around the avatar, or a
/// prebuilt model (an edited garment read back); a material, pins.
struct GarmentSpec {
  std::string name = "cloth";
  /// Name of a material of the scene or a built-in one ("stiff_cotton", "blender_cotton").
  std::string material = "stiff_cotton";
  /// Exactly one of panel, mesh, pattern or model is set.
  std::optional<LatticePanel> panel;
  std::optional<SurfaceMesh> mesh;
  /// A built-in garment ("skirt", "cape", "dress": garment_patterns.h), fitted to the
  /// scene's avatar and attached to it; needs an avatar.
  std::optional<std::string> pattern;
  /// A prebuilt model used as it is: rest positions, masses, springs with their stiffness,
  /// damping and (possibly edited) rest lengths, and its own pinned particles (pin_points
  /// are ignored; the material is not used to build it). With attach_to, the model's pinned
  /// particles are held by that joint. Saved garments come back this way
  /// (assets/edited_garment.h).
  std::shared_ptr<const ClothModel> model;
  /// Particles around the pattern's circumference, in [8, 1024].
  int pattern_resolution = 64;
  /// Pinned particles: the particle nearest to each point is pinned [m].
  std::vector<Eigen::Vector3d> pin_points;
  /// A pin point must have a particle within this distance [m].
  double pin_tolerance = 1e-3;
  /// When set, the pinned particles are held by this joint of the scene's avatar and move
  /// with it (a waistband, a collar) instead of staying fixed in space; needs an avatar.
  std::optional<HAnimJoint> attach_to;
  /// Mesh garments modelled on the skin with no thickness (MakeHuman's): before the cloth
  /// is built, the mesh is moved out of the avatar's rest surface to the collision
  /// thickness + 1 mm (FitOutsideBody, garment_fit.h), and the rest lengths
  /// are those of the moved mesh; pin points are matched on the mesh as given. Needs a mesh
  /// and an avatar whose surface is closed. Off: the mesh is used as it is.
  bool fit_outside_body = false;
  /// A mesh garment modelled on one body (a MakeHuman garment fitted to the MakeHuman body
  /// it came with): worn only by an avatar with that body's rest skin (SameRestSkin), which
  /// ValidateScene checks. Moved out of another body, the suits' welded hems became springs
  /// too stiff for any step. Null: any avatar.
  std::shared_ptr<const Avatar> made_for;
  /// Line of the garment's table in the scene file (0 when not from a file), for messages.
  int source_line = 0;
};

/// How cloth collides with the avatar (paper §4).
enum class BodyCollisionMethod {
  /// One fitted superquadric per H-Anim segment with the skin's distance mapped over it.
  kSuperquadric,
  /// The skinned mesh through Bullet's BVH with curvature-adaptive regions.
  kMesh,
};

/// "superquadric" or "mesh".
const char* BodyCollisionMethodName(BodyCollisionMethod method);

/// The most memory a scene may give the superquadric method's stored drawings
/// (AvatarSpec::superquadric_map_mb) [MB].
constexpr double kMaxSuperquadricMapMb = 16384.0;

/// The most steps AvatarSpec::max_steps_per_frame may allow.
constexpr int kMaxStepsPerFrame = 64;

/// Largest gravity component a scene may set [m/s²]: ten times the Earth's. A scene file with
/// a gravity of 1e9 m/s² ran, stretching the cloth by 66 million per cent without a word.
constexpr double kMaxGravity = 100.0;

/// Largest cloth thickness kept off the avatar's skin or a sphere [m].
constexpr double kMaxThickness = 0.05;

/// The avatar a scene dresses, already loaded (the assets layer resolves files and names).
struct AvatarSpec {
  std::shared_ptr<const Avatar> avatar;
  /// The clip it plays (any skeleton with H-Anim joints; retargeted); null to hold still.
  std::shared_ptr<const Clip> clip;
  /// Posture, placement, fitting and blend times, and the arms' spread (used as given
  /// only when auto_arm_spread is false).
  AvatarMotionSettings motion;
  /// Whether the simulation chooses the arms' spread for the clip (FindArmSpread,
  /// arm_spread.h) instead of taking motion.arm_spread.
  bool auto_arm_spread = true;
  /// The mesh method by default: it is faster on the first pass through a clip and on any
  /// motion that does not repeat (a posture being set); the superquadric one is 1.5–2.9× as
  /// fast on a looping clip's later passes, where it reuses its maps' drawings. Both keep
  /// the cloth within 2 mm of the skin and stretch it alike (docs/collision.md, "Figures",
  /// "Contacts that pulled").
  BodyCollisionMethod collision = BodyCollisionMethod::kMesh;
  /// Superquadric method: memory for its maps' drawings kept for reuse when the skin comes
  /// back, as a looping clip brings it every pass [MB] in [0, kMaxSuperquadricMapMb]; 0
  /// draws every map afresh.
  double superquadric_map_mb = 256.0;
  /// Cloth thickness kept off the skin [m] in [0, 0.05].
  double thickness = 0.004;
  /// Coulomb friction between cloth and skin [-] in [0, 2].
  double friction = 0.5;
  /// Farthest the skin near the cloth may move within one step [m] in [0, 1]; a frame in
  /// which it moves farther is split into more steps (up to max_steps_per_frame). Collision
  /// is tested where a step starts and ends, so a limb that crosses cloth within one step
  /// (a kicking foot: 20 cm a frame) leaves it on its far side, threaded round the limb.
  /// 0: never split (solver.substeps steps every frame). At 5 cm the benchmark's walks are
  /// not split, and its kick takes a quarter more steps and stretches the skirts' worst
  /// springs a third to a sixth as far (docs/collision.md, "Fast limbs"). Measured relative
  /// to the body's root, which the garments hang from.
  double max_skin_travel = 0.05;
  /// Most steps a frame is split into for the skin's travel, in [1, kMaxStepsPerFrame];
  /// never fewer than solver.substeps.
  int max_steps_per_frame = 8;
  int source_line = 0;
};

/// A fixed analytic sphere obstacle.
struct SphereObstacleSpec {
  /// Centre [m], each coordinate within ±kMaxCoordinate.
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  /// Radius [m] in (0, kMaxCoordinate].
  double radius = 0.25;
  /// Cloth thickness kept between cloth and surface [m] in [0, kMaxThickness].
  double thickness = 0.005;
  /// Coulomb friction coefficient [-] in [0, kMaxFriction] (used when effects.friction is on).
  double friction = 0.3;
  int source_line = 0;
};

/// A whole run.
struct SceneDescription {
  std::string name = "scene";
  /// Where the scene came from (file path or "built-in"), for messages.
  std::string source = "built-in";
  /// Simulated duration [s] > 0.
  double duration = 2.0;
  /// Frames per second written and timed [Hz] > 0.
  double frame_rate = 60.0;
  /// Gravity [m/s²].
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, -9.81, 0.0);
  SolverSettings solver;
  Effects effects;
  /// Materials defined in the scene (looked up by name before the built-in ones).
  std::vector<Material> materials;
  std::vector<GarmentSpec> garments;
  std::vector<SphereObstacleSpec> spheres;
  /// The avatar; none for the benchmark scenes.
  std::optional<AvatarSpec> avatar;
};

/// How cloth collides, as a running scene changes it (Simulation::SetCollision, the GUI's
/// Collision tab): the avatar's collision fields (AvatarSpec, which documents them) and the
/// self-collision switch (Effects). Filled from a scene by CollisionSettingsOf.
struct CollisionSettings {
  BodyCollisionMethod method = BodyCollisionMethod::kMesh;
  double superquadric_map_mb = 0.0;  ///< [MB]
  double thickness = 0.0;            ///< [m]
  double friction = 0.0;             ///< [-]
  double max_skin_travel = 0.0;      ///< [m]; 0: never split a frame
  int max_steps_per_frame = 1;
  bool self_collision = false;
};

/// The scene's collision settings: its avatar's, or AvatarSpec's defaults when it has none.
CollisionSettings CollisionSettingsOf(const SceneDescription& scene);

/// Writes `settings` into `scene`: effects.self_collision, and the avatar's fields when it
/// has an avatar (without one they have nothing to act on and are dropped).
void ApplyCollisionSettings(const CollisionSettings& settings, SceneDescription& scene);

/// Checks ranges that do not need a file (solver, rates, obstacles, garments have a shape);
/// throws InputError naming scene.source and the field. BuildSimulation calls it.
/// Messages read `<source>[:<line>]: <field> = <value>: <allowed range>`, e.g.
/// `built-in: solver.tolerance = 2: allowed range (0, 1)`; the line is that of a garment or
/// sphere from a file (source_line > 0). The ranges are those of docs/scene_format.md, which
/// the scene file parser (assets/scene_file.h) checks first with line and column.
void ValidateScene(const SceneDescription& scene);

}  // namespace costume::sim
