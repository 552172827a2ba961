#pragma once
/// @file
/// A running scene: the garments merged into one cloth model, its state, the implicit
/// stepper and the obstacles the scene enables (and nothing it does not).

#include <memory>
#include <string>
#include <vector>

#include "sim_core/common/thread_pool.h"
#include "sim_core/avatar/avatar_motion.h"
#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"
#include "sim_core/collision/body_collider.h"
#include "sim_core/collision/contact.h"
#include "sim_core/collision/self_collision.h"
#include "sim_core/collision/sphere_contacts.h"
#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/scene/arm_spread.h"
#include "sim_core/scene/body_colliders.h"
#include "sim_core/scene/grab.h"
#include "sim_core/scene/scene_description.h"
#include "sim_core/solver/implicit_stepper.h"
#include "sim_core/solver/strain_limit.h"

namespace costume::sim {

/// Where one garment lives inside the merged model.
struct GarmentRange {
  std::string name;
  int first_particle = 0;
  int num_particles = 0;
  int first_triangle = 0;
  int num_triangles = 0;
};

/// A particle held to the avatar: it follows `joint`'s rigid motion from the rest pose.
struct BodyAttachment {
  int particle = 0;
  /// Joint index in the avatar's skeleton.
  int joint = 0;
  /// The particle's rest position in the joint's rest frame [m].
  Eigen::Vector3d local = Eigen::Vector3d::Zero();
};

/// What happened during one frame (all substeps).
struct FrameReport {
  int steps = 0;
  /// Level-0 solver iterations summed over the frame's steps.
  int iterations = 0;
  /// Coarse-level iterations of the hierarchical step, summed over the frame's steps.
  int coarse_iterations = 0;
  /// Every step reached its solver tolerance.
  bool converged = true;
  /// Steps that produced non-finite values and were undone (see StepReport).
  int rolled_back_steps = 0;
  /// Contacts summed over the frame's steps.
  int num_contacts = 0;
  /// Springs shortened by the strain limit, summed over the frame's steps.
  int strain_corrections = 0;
  /// Deepest penetration into an obstacle's shell found after a solve, before the position
  /// correction removed it [m].
  double max_penetration = 0.0;
  /// Time spent finding contacts with the avatar and correcting positions [ms].
  double collision_ms = 0.0;
  /// Time the avatar's collider spent following the body to each step's pose [ms]
  /// (BodyCollider::Update: the mesh method's refit, the superquadric method's placements
  /// and skin in the segments' frames); not in `collision_ms`.
  double collision_update_ms = 0.0;
  /// Superquadric method: distance maps drawn from the skin, and maps that reused a stored
  /// drawing of the same skin, summed over the frame's steps (BodyCollisionStats).
  int maps_drawn = 0;
  int maps_reused = 0;
  /// Superquadric method: position corrections that the skin triangles decided where no map
  /// could (BodyCollisionStats::num_skin_checks), summed over the frame's steps.
  int skin_checks = 0;
  /// Mesh method: winding-number counts, and particles they found buried in skin and
  /// moved out (BodyCollisionStats::num_winding_checks, num_buried), summed over the
  /// frame's steps.
  int winding_checks = 0;
  int buried = 0;
  /// Time spent on self-collision [ms] (0 when the scene switches it off).
  double self_collision_ms = 0.0;
  /// Time the implicit solve took (assembly, solver, rollback checks) [ms], and the strain
  /// limit's projections after it [ms], summed over the frame's steps.
  double solve_ms = 0.0;
  double strain_limit_ms = 0.0;
  /// Cloth–cloth collisions self-collision could not resolve, summed over the steps.
  int unresolved_self_collisions = 0;
  /// Wall-clock time of the frame [ms].
  double wall_ms = 0.0;
};

class Simulation {
 public:
  /// Builds the engine for `scene` (validated first). Throws InputError naming the scene
  /// source, the field, the value and the allowed range. `arm_spreads` (when not null)
  /// remembers the arms' spread chosen for the avatar's clip, so that rebuilding the same
  /// scene does not search again (a server's STOP, a new fabric); `colliders` (when not
  /// null) keeps the avatar's superquadric collider for the next simulation built for it,
  /// which then shares it: step only the last one built (body_colliders.h).
  static std::unique_ptr<Simulation> Build(const SceneDescription& scene,
                                           ArmSpreadMemo* arm_spreads = nullptr,
                                           ColliderMemo* colliders = nullptr);

  /// Advances one frame (1/frame_rate s, in solver.substeps steps, or more where the avatar's
  /// skin near the cloth moves farther than AvatarSpec::max_skin_travel within a step;
  /// FrameReport::steps says how many). Never throws.
  FrameReport AdvanceFrame();

  // ---- editing (mode B, paper §5) ------------------------------------------------------
  /// The designer grabs the cloth: from the next step on, the particles within the grab's
  /// radius of its centre feel F_h·g(x) (grab.h). The particles are selected when the grab
  /// starts (the first SetGrab after a release) and stay held as later calls move the
  /// sphere and change the force. Collision with the avatar stays on: a grab cannot push
  /// cloth into the body. Returns false and changes nothing for a grab with non-finite
  /// fields or a radius <= 0. Never throws.
  bool SetGrab(const Grab& grab);
  /// Lets go: the cloth returns to its rest shape unless the stretch was made permanent.
  void ReleaseGrab();
  bool grabbing() const { return grabbing_; }
  /// The grab last set (meaningful while grabbing()).
  const Grab& grab() const { return grab_; }
  /// The particles the grab holds.
  const std::vector<int>& grabbed() const { return grabbed_; }
  /// The force for the device after the last step [N]: the spring forces the rest of the
  /// cloth exerts on the grabbed particles, pulling against the grab (grab.h; zero when not
  /// grabbing).
  const Eigen::Vector3d& grab_feedback() const { return grab_feedback_; }
  /// "Eliminate stretch energy" (paper §5.3): every spring with both ends within `radius`
  /// [m] of `centre` [m] takes its current length as rest length, so the cloth stays where
  /// it was left. A new model revision; the pyramid's coarse levels are brought in line for
  /// that region only. Returns the number of springs changed (0 for non-finite input or an
  /// empty region). The previous revision is kept for UndoEdit. Never throws.
  int EliminateStretchEnergy(const Eigen::Vector3d& centre, double radius);
  /// Restores the rest lengths before the last EliminateStretchEnergy (repeatable down to
  /// the model the scene was built with); false when there is nothing to undo.
  bool UndoEdit();
  /// Changes the solver settings (method, levels, tolerance, iterations, substeps, strain
  /// limit) in place: the state, the edited rest lengths, the undo history, the grab and the
  /// avatar's clock are kept, so the positions at the switch are bit for bit those before it.
  /// The new solver is built around the current model (a pyramid's coarse levels from the
  /// edited level 0). Throws InputError (ValidateScene, RequireStableStep) and changes
  /// nothing for settings the scene would refuse.
  void SetSolver(const SolverSettings& solver);

  /// Changes how cloth collides (CollisionSettings: the avatar's method, thickness, friction,
  /// skin travel per step and map memory, and self-collision) in place, as SetSolver does:
  /// the state, the edits, the undo history, the grab and the avatar's clock are kept, and
  /// the next step uses the new settings. A new method builds a new collider around the
  /// avatar where it stands (the superquadric method fits its segments: 0.4–0.9 s, unless
  /// `colliders` kept one for the avatar); a new thickness, friction or map memory is given
  /// to the collider there is (ApplyColliderSettings in body_colliders.h; a new map memory
  /// drops the stored drawings); self-collision switched on is built, switched off freed.
  /// Without an avatar only self-collision applies. `colliders` (when not null) gives a new
  /// collider as for Build, and keeps it for the next build. Throws InputError
  /// (ValidateScene) and changes nothing for settings the scene would refuse.
  void SetCollision(const CollisionSettings& settings, ColliderMemo* colliders = nullptr);

  /// Edits that UndoEdit can still take back.
  int num_undoable_edits() const { return static_cast<int>(undo_.size()); }

  // ---- the avatar's clock (mode B freezes it, paper §5) --------------------------------
  /// Freezes (true) or resumes (false) the avatar's clock while the cloth keeps simulating:
  /// in mode B the designer edits the cloth on a motionless body. Frozen, every step poses
  /// the avatar at the time it was frozen; resumed, the clip carries on from that time (the
  /// frozen interval is skipped, not caught up). Never frozen, the avatar is posed at
  /// state().time exactly as before this switch existed. No effect without an avatar.
  void SetAvatarFrozen(bool frozen);
  bool avatar_frozen() const { return avatar_frozen_; }
  /// The time the avatar is posed at after the last step [s]: state().time minus the
  /// simulated time spent frozen.
  double avatar_time() const;

  /// The designer poses the avatar (paper §6) while the cloth keeps its state: the body
  /// moves from its current pose to `posture` (rotations per joint, placement) over
  /// `transition_time` [s] >= 0 of simulated time, frozen avatar clock or not, and the cloth
  /// follows it through contacts and attachments. The scene's posture becomes `posture` (a
  /// later rebuild uses it). The arms' spread changes as `spread` asks, over the same
  /// transition; kAuto searches for it in the new posture (FindArmSpread, 0.01–0.5 s),
  /// unless `arm_spreads` (when not null) remembers the answer. Returns false and changes
  /// nothing without an avatar. Throws InputError for a posture of the wrong size,
  /// non-finite values, a spread out of range or a negative time.
  bool SetPosture(const Pose& posture, double transition_time,
                  const ArmSpreadRequest& spread = {}, ArmSpreadMemo* arm_spreads = nullptr);

  const SceneDescription& scene() const { return scene_; }
  const ClothModel& model() const { return stepper_->model(); }
  std::shared_ptr<const ClothModel> shared_model() const { return model_; }
  const ClothState& state() const { return state_; }
  ClothState& mutable_state() { return state_; }
  const std::vector<GarmentRange>& garments() const { return garments_; }
  /// The avatar as it moves (null when the scene has none).
  const AvatarMotion* avatar() const { return avatar_.get(); }
  /// The avatar's collider (null when the scene has no avatar).
  const BodyCollider* body_collider() const { return body_.get(); }
  const std::vector<BodyAttachment>& attachments() const { return attachments_; }
  /// The arms' spread the avatar plays its clip with, and what FindArmSpread measured
  /// (`measured` false when the scene gave the spread or has no clip).
  const ArmSpreadFit& arm_spread() const { return arm_spread_; }
  /// The pyramid the hierarchical and multigrid solvers use; null for the others.
  const QuincunxPyramid* pyramid() const { return pyramid_.get(); }
  /// Step length [s] of a frame that is not split for the skin's travel.
  double step() const {
    return 1.0 / (scene_.frame_rate * std::max(scene_.solver.substeps, stiffness_steps_));
  }
  /// Number of frames the scene's duration asks for.
  int num_frames() const;

 private:
  Simulation(SceneDescription scene, std::shared_ptr<const ClothModel> model,
             std::vector<GarmentRange> garments, std::vector<BodyAttachment> attachments,
             const StepperSettings& settings, ArmSpreadMemo& arm_spreads,
             ColliderMemo* colliders);
  /// Steps for the coming frame: solver.substeps, or as many as keep the skin near the
  /// cloth within AvatarSpec::max_skin_travel a step. Measuring poses the avatar at the
  /// frame's end (`posed_at_end`); a split frame's first step poses it again.
  int StepsThisFrame(bool& posed_at_end);
  /// One step of h [s]; `avatar_posed`: the avatar already stands where the step ends.
  void StepOnce(double h, bool avatar_posed, FrameReport& report);
  /// The time the avatar is posed at, and the posture transition's blend, `dt` [s] after
  /// state_.time.
  double AvatarTimeAfter(double dt) const;
  double PostureBlendAfter(double dt) const;
  void MoveAvatar(double t, double h, bool posed, FrameReport& report);
  void StartGrab();
  /// Points the stepper at the grab's forces or anchors (or at none when not grabbing).
  void ConnectGrab();
  /// A new pyramid (when the method uses one) and stepper around model_ for `settings`.
  void BuildSolver(const StepperSettings& settings);
  /// `settings` with the solver's loops on pool_.
  StepperSettings OnOwnThreads(StepperSettings settings) const;
  void UpdateGrabForces();
  void FindContacts(double h, FrameReport& report);
  void ReleaseAdhesiveContacts(double h);
  /// After the solve: the strain limit, the obstacles' and the body's position corrections,
  /// the attachments, the grab's feedback, self-collision (with the strain limit after it).
  void CorrectAfterSolve(double h, FrameReport& report);
  /// The body's position correction (BodyCollider::ProjectOut) and the attachments; keeps
  /// the solved positions first when self-collision needs them.
  void ProjectOutOfBody(FrameReport& report);
  /// After the body's correction of a copy in ApplyStrainLimit: which particles it left
  /// alone, and where it saw them.
  void NoteWhatTheBodyLeftAlone();
  /// The particles the body's correction must look at now: all, or after
  /// NoteWhatTheBodyLeftAlone in this step those it moved and those that moved since.
  const std::vector<int>& NeedingBodyCorrection();
  /// After self-collision's Resolve: the strain limit again (16 sweeps) and, when it
  /// shortened any spring, SelfCollision::ResolveCrossings over that correction (the body's
  /// holds kept); again while that resolve stops anything, up to four rounds.
  void LimitWhatSelfCollisionStretched(double h, FrameReport& report);
  /// After self-collision: the body's correction again, and when it moved anything, a second
  /// Resolve over that move with the moved particles held, so that self-collision leaves
  /// neither cloth in the body nor an edge through the cloth; then the particles that
  /// Resolve moved into the skin go back onto it (the body wins where both cannot hold).
  void ResolveWhatTheBodyMovesBack(double h, FrameReport& report);
  /// BodyCollider::ProjectOutOfSkin for the particles that moved from `before_move_`.
  void ProjectOutWhatResolveMoved(FrameReport& report);
  /// Puts the attached particles where the body holds them.
  void PlaceAttachments();
  void AddBodyStats(FrameReport& report) const;
  /// The particles the body holds in this step, for self-collision (BodyHold): those with a
  /// contact in this step or the last, and those the body's correction moved (along the move).
  void CollectBodyHolds();
  /// Adds (or turns along the move) a hold for each particle the body's correction moved
  /// from `solved_positions_`; returns whether it moved any.
  bool HoldWhatTheBodyMoved();
  /// The strain limit with the obstacles' shells held: the contacts' planes, then the planes
  /// the obstacles' corrections would move cloth to (strain_limit.h).
  void ApplyStrainLimit(FrameReport& report);
  StrainLimitSettings StrainLimitOf() const;
  /// The strain limiter for model_ (its tethers' rest distances are the model's), or none
  /// when solver.strain_limit is 0.
  void BuildStrainLimiter();
  /// The steps a frame needs for the model's stiffness with the strain limit on
  /// (StepsForStiffness); 1 without it.
  int StiffnessSteps() const;
  /// Keeps the state finite: a step that ends non-finite anywhere (the stepper undoes only
  /// its solve; the corrections after it work with what the body gives) returns to the last
  /// finite state, counted in `rolled_back_steps` unless the stepper counted it
  /// (`stepper_rolled_back`). Returns whether the state was finite (the step stands). Never
  /// throws or allocates.
  bool KeepFinite(bool stepper_rolled_back, FrameReport& report);

  SceneDescription scene_;
  std::shared_ptr<const ClothModel> model_;
  std::vector<GarmentRange> garments_;
  /// The solver's threads beyond this one (solver.threads); null when it runs alone.
  std::unique_ptr<ThreadPool> pool_;
  /// The quincunx pyramid, for the hierarchical and multigrid solvers (null otherwise).
  std::shared_ptr<QuincunxPyramid> pyramid_;
  /// Rebuilt by SetSolver (hence a pointer); never null.
  std::unique_ptr<ImplicitStepper> stepper_;
  ClothState state_;
  std::vector<SphereObstacle> spheres_;
  std::unique_ptr<AvatarMotion> avatar_;
  /// Shared with a ColliderMemo, when built with one.
  std::shared_ptr<BodyCollider> body_;
  std::vector<BodyAttachment> attachments_;
  ArmSpreadFit arm_spread_;
  /// Built only when the scene switches self-collision on (off costs nothing).
  std::unique_ptr<SelfCollision> self_collision_;
  /// Built only when solver.strain_limit > 0.
  std::unique_ptr<StrainLimiter> strain_limiter_;
  /// The state as the obstacles' corrections would leave it, and the planes they would move
  /// cloth to (ApplyStrainLimit).
  Points corrected_positions_, corrected_velocities_;
  std::vector<ShellPlane> correction_planes_;
  /// Whether the body's correction in ApplyStrainLimit saw the cloth this step, and the
  /// particles it left alone there (1): ProjectOutOfBody looks again only at the others and
  /// at those that moved since (NeedingBodyCorrection), as the body has not moved.
  bool body_saw_this_step_ = false;
  /// The part of ApplyStrainLimit's time the body's correction took [ms], counted as
  /// collision time.
  double collision_in_limit_ms_ = 0.0;
  std::vector<char> body_left_alone_;
  std::vector<int> body_recheck_;
  /// Steps every frame takes at least, for the model's stiffness (StiffnessSteps).
  int stiffness_steps_ = 1;
  /// Positions at the start of the step, for self-collision's continuous tests.
  Points start_positions_;
  /// Positions before the body's last correction (self-collision only).
  Points solved_positions_;
  /// Positions before each round of LimitWhatSelfCollisionStretched's strain limit.
  Points self_resolved_;
  /// Positions before the second Resolve, and the particles it moved (self-collision only).
  Points before_move_;
  std::vector<int> moved_by_resolve_;
  /// This step's and the last step's body holds, and each particle's hold (or -1).
  std::vector<BodyHold> body_holds_, previous_holds_;
  std::vector<int> hold_of_;
  /// The state after the last step that ended finite (KeepFinite).
  ClothState last_finite_;
  std::vector<Contact> contacts_;
  /// The velocities the particles would have at the end of the step under gravity alone,
  /// which FindContacts judges contacts by.
  Points coasting_;
  /// The grab and what it does; `applied_` is what the stepper adds (n×3) [N].
  Grab grab_;
  bool grabbing_ = false;
  /// Where the sphere was when the grab started [m]; each grabbed particle's position then
  /// [m] and its Gaussian weight there (a coupling grab's springs keep both).
  Eigen::Vector3d grab_start_centre_ = Eigen::Vector3d::Zero();
  Points grab_start_positions_;
  std::vector<double> grab_start_weights_;
  Points applied_;
  Points anchor_targets_;
  Eigen::VectorXd anchor_stiffness_;
  std::vector<int> grabbed_;
  std::vector<char> is_grabbed_;
  Eigen::Vector3d grab_feedback_ = Eigen::Vector3d::Zero();
  /// Earlier model revisions, every pyramid level's, newest last.
  std::vector<std::vector<std::shared_ptr<const ClothModel>>> undo_;
  /// The avatar's clock: frozen at `frozen_avatar_time_` [s], or state_.time − avatar_lag_
  /// [s], the lag being the simulated time spent frozen (0 until the first freeze).
  bool avatar_frozen_ = false;
  double frozen_avatar_time_ = 0.0;
  double avatar_lag_ = 0.0;
  /// The posture transition (SetPosture): started at simulated time `posture_start_` [s],
  /// lasting `posture_duration_` [s] (0: none under way).
  double posture_start_ = 0.0;
  double posture_duration_ = 0.0;
  /// Each particle's contact normal impulse in the last step [N·s]: its positive part bounds
  /// friction, a negative one releases the contact. The last step's length [s] (steps differ
  /// where a frame is split for the skin's travel, and friction needs the force).
  std::vector<double> normal_impulse_;
  double last_step_ = 0.0;
  /// Each particle's fabric friction, mixed into its contacts' (MixFriction); -1: none.
  std::vector<double> fabric_friction_;
  /// The skin where the frame starts (StepsThisFrame's measure).
  Points frame_start_skin_;
  /// Whether some cloth is pinned in the room rather than held by the avatar: the skin's
  /// travel then counts the root's too (StepsThisFrame).
  bool pinned_in_room_ = false;
};

/// Refuses `model` for `scene` (InputError naming scene.source) when its step cannot run it:
/// with the strain limit off, RequireStableStep (implicit_stepper.h) for solver.substeps;
/// with it on, only when more than kMaxSubsteps steps a frame would be needed
/// (StepsForStiffness at kMaxLimitedStiffnessRatio), which the engine takes itself.
void RequireStableStepFor(const SceneDescription& scene, const ClothModel& model);

/// The stepper settings a scene asks for.
StepperSettings StepperSettingsOf(const SceneDescription& scene);

/// The thread count solver.threads = `threads` stands for (kMachineThreads: the machine's).
int SolverThreads(int threads);
/// A pool of SolverThreads(threads) threads; null when that is one.
std::unique_ptr<ThreadPool> MakeThreadPool(int threads);

/// Merges the scene's garments into one model (panels, meshes and patterns, materials
/// resolved, pins found, pattern garments fitted to the avatar and their attached particles
/// pinned and listed in `attachments`). Throws InputError. Exposed for tools and tests.
std::shared_ptr<const ClothModel> BuildSceneModel(const SceneDescription& scene,
                                                  std::vector<GarmentRange>* garments,
                                                  std::vector<BodyAttachment>* attachments);

}  // namespace costume::sim
