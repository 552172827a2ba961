#include "sim_core/scene/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "sim_core/avatar/garment_patterns.h"
#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/cloth/mesh_cloth.h"
#include "sim_core/common/input_error.h"
#include "sim_core/hierarchy/step_solvers.h"
#include "sim_core/scene/garment_fit.h"
#include "sim_core/solver/strain_limit.h"

namespace costume::sim {

namespace {

/// How far beyond the collision thickness a fitted garment starts [m]: clear of the shell,
/// so that the first step finds it resting on the shell rather than inside.
constexpr double kFitClearanceExtra = 0.001;

/// A body correction's move shorter than this [m] is rounding, not a move: it neither holds
/// a particle (its direction would be noise) nor calls for a second Resolve (the mesh
/// method's correction moves resting particles by 1e-17 m in most steps). The same length
/// self-collision takes as no motion.
constexpr double kNoMove = 1e-12;

/// The farthest a skin vertex that can reach the cloth moves from `start` to `end` relative
/// to the body's root, which moves by `root_shift` [m] (zero for cloth pinned in the room):
/// garments hang from the body and go where its root takes them, so a clip travelling across
/// the room is no faster for the cloth than one in place. A vertex counts when its start lies
/// within its own travel of the cloth's bounding box grown by the thickness (a hand swinging
/// far from a skirt does not).
double SkinTravelNearCloth(const Points& start, const Points& end,
                           const Eigen::Vector3d& root_shift, const Points& cloth,
                           double thickness) {
  if (cloth.rows() == 0 || start.rows() != end.rows()) return 0.0;
  const Eigen::Array3d lo = cloth.colwise().minCoeff().transpose().array() - thickness;
  const Eigen::Array3d hi = cloth.colwise().maxCoeff().transpose().array() + thickness;
  double farthest = 0.0;
  for (Eigen::Index v = 0; v < start.rows(); ++v) {
    const double travel = ((end.row(v) - start.row(v)).transpose() - root_shift).norm();
    if (!(travel > farthest)) continue;
    const Eigen::Array3d a = start.row(v).transpose().array();
    const Eigen::Array3d outside = (lo - a).max(a - hi).max(0.0);
    if (outside.matrix().norm() <= travel) farthest = travel;
  }
  return farthest;
}

/// Whether a pinned particle of `model` is held by no joint (`attachments`): cloth pinned in
/// the room, which a body travelling across it meets at the root's speed too.
bool PinnedInRoom(const ClothModel& model, const std::vector<BodyAttachment>& attachments) {
  std::vector<bool> held(model.num_particles(), false);
  for (const BodyAttachment& a : attachments) held[a.particle] = true;
  for (int i = 0; i < model.num_particles(); ++i) {
    if (model.is_pinned()[i] && !held[i]) return true;
  }
  return false;
}

/// Wall-clock time since `start` [ms], for the frame report.
double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

std::string GarmentContext(const SceneDescription& scene, const GarmentSpec& garment) {
  // Appended piece by piece: GCC 12 warns (-Wrestrict, falsely) about ":" + to_string here.
  std::string where = scene.source;
  if (garment.source_line > 0) where.append(":").append(std::to_string(garment.source_line));
  return where.append(": garment '").append(garment.name).append("'");
}

/// The material a garment names: the scene's own first, then the built-in ones. Blender's
/// per-spring preset depends on the lattice size, so it is resolved against the panel.
Material ResolveMaterial(const SceneDescription& scene, const GarmentSpec& garment) {
  for (const Material& m : scene.materials) {
    if (m.name == garment.material) return m;
  }
  if (garment.material == "blender_cotton") {
    return BlenderCotton(garment.panel ? garment.panel->cols : 65);
  }
  const std::vector<std::string> named = NamedMaterialNames();
  if (std::find(named.begin(), named.end(), garment.material) != named.end()) {
    return NamedMaterial(garment.material);
  }
  std::string known;
  for (const Material& m : scene.materials) known += m.name + ", ";
  for (const std::string& name : named) known += name + (name == named.back() ? "" : ", ");
  throw InputError(GarmentContext(scene, garment) + ": material = '" + garment.material +
                   "' is unknown: known materials are " + known);
}

/// Holds the pinned particles of `data` by `joint` of the scene's avatar — or by its nearest
/// H-Anim ancestor the avatar maps (MakeHuman's skeleton has no separate sacroiliac: a skirt
/// hangs from its root) — listing them in `attachments` (indices local to the garment).
void Attach(const SceneDescription& scene, const GarmentSpec& garment, HAnimJoint joint,
            const ClothModelData& data, std::vector<BodyAttachment>& attachments) {
  const Avatar& avatar = *scene.avatar->avatar;
  std::optional<HAnimJoint> holder = joint;
  while (holder && avatar.skeleton().Find(*holder) < 0) holder = HAnimParent(*holder);
  if (!holder) {
    throw InputError(GarmentContext(scene, garment) + ": avatar '" + avatar.name() +
                     "' maps no H-Anim joint at or above '" + std::string(HAnimName(joint)) +
                     "' to hold the garment");
  }
  const int index = avatar.skeleton().Find(*holder);
  const Eigen::Isometry3d to_joint = avatar.skeleton().rest_world()[index].inverse();
  for (int p : data.pinned) {
    attachments.push_back({p, index, to_joint * Eigen::Vector3d(data.rest_positions.row(p))});
  }
}

/// A pattern garment fitted to the scene's avatar; its attached particles are pinned and
/// listed in `attachments` (indices local to the garment).
ClothModelData BuildPatternGarment(const SceneDescription& scene, const GarmentSpec& garment,
                                   const Material& material,
                                   std::vector<BodyAttachment>& attachments) {
  const Avatar& avatar = *scene.avatar->avatar;
  GarmentPattern pattern = MakeBuiltInGarment(*garment.pattern, MeasureBody(avatar), material,
                                              garment.pattern_resolution);
  pattern.data.name = garment.name;
  pattern.data.pinned = pattern.attached;
  Attach(scene, garment, pattern.attached_to, pattern.data, attachments);
  return std::move(pattern.data);
}

/// The mesh of a mesh garment, moved out of the avatar's rest surface when the garment
/// asks for it (fit_outside_body): it then starts outside the collider's shell, with rest
/// lengths measured there.
SurfaceMesh FittedMesh(const SceneDescription& scene, const GarmentSpec& garment) {
  if (!garment.fit_outside_body) return *garment.mesh;
  const AvatarSpec& spec = *scene.avatar;
  return FitOutsideBody(*garment.mesh, spec.avatar->rest_vertices(), spec.avatar->triangles(),
                        spec.thickness + kFitClearanceExtra);
}

ClothModelData BuildGarment(const SceneDescription& scene, const GarmentSpec& garment,
                            std::vector<BodyAttachment>& attachments) {
  if (garment.model) {  // prebuilt: its springs already carry the material (and any edits)
    ClothModelData data = garment.model->data();
    data.name = garment.name;
    if (garment.attach_to) Attach(scene, garment, *garment.attach_to, data, attachments);
    return data;
  }
  const Material material = ResolveMaterial(scene, garment);
  if (garment.pattern) return BuildPatternGarment(scene, garment, material, attachments);
  ClothModelData data = garment.panel
                            ? BuildLatticePanel(*garment.panel, material, garment.name)
                            : BuildMeshCloth(FittedMesh(scene, garment), material, garment.name);
  // Pins name points of the garment as given, before any fitting moved them.
  data.pinned = FindNearestParticles(garment.mesh ? garment.mesh->vertices : data.rest_positions,
                                     garment.pin_points, garment.pin_tolerance,
                                     GarmentContext(scene, garment));
  if (garment.attach_to) Attach(scene, garment, *garment.attach_to, data, attachments);
  return data;
}

/// Appends `part` to `whole`, shifting its indices.
void Append(ClothModelData& whole, const ClothModelData& part) {
  const int offset = static_cast<int>(whole.masses.size());
  const auto n = part.masses.size();
  auto grow = [n](Eigen::VectorXd& v, const Eigen::VectorXd& tail) {
    v.conservativeResize(v.size() + n);
    v.tail(n) = tail;
  };
  whole.rest_positions.conservativeResize(offset + n, 3);
  whole.rest_positions.bottomRows(n) = part.rest_positions;
  grow(whole.masses, part.masses);
  grow(whole.areas, part.areas);
  grow(whole.drag, part.drag.size() ? part.drag : Eigen::VectorXd::Zero(n).eval());
  for (Spring s : part.springs) {
    s.a += offset;
    s.b += offset;
    whole.springs.push_back(s);
  }
  for (int p : part.pinned) whole.pinned.push_back(p + offset);
  for (const Eigen::Vector3i& t : part.triangles) {
    whole.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  }
}

/// What the scene's avatar collider is built with, or given in place: the thickness, and
/// the skin's friction coefficient the contacts carry (before the fabric's is mixed in),
/// none when the scene switches friction off.
BodyCollisionSettings ContactSettings(const SceneDescription& scene) {
  BodyCollisionSettings contact;
  contact.thickness = scene.avatar->thickness;
  contact.friction = scene.effects.friction ? scene.avatar->friction : 0.0;
  return contact;
}

/// The collider the scene's avatar asks for (`memo`'s when it keeps one for it, when not
/// null), following the avatar where it stands now (`h` [s]: the step its skin velocities
/// are taken over until the next Update).
std::shared_ptr<BodyCollider> MakeAvatarCollider(const SceneDescription& scene,
                                                 const AvatarMotion& avatar, double h,
                                                 ColliderMemo* memo) {
  const AvatarSpec& spec = *scene.avatar;
  const BodyCollisionSettings contact = ContactSettings(scene);
  std::shared_ptr<BodyCollider> body =
      memo ? memo->Find(spec.collision, spec.avatar, contact, spec.superquadric_map_mb)
           : MakeBodyCollider(spec.collision, spec.avatar, contact, spec.superquadric_map_mb);
  body->Update(avatar.joint_world(), avatar.vertices(), h);
  return body;
}

/// Each particle's fabric friction (MixFriction's `fabric`), from its garment's material;
/// -1 for a prebuilt garment whose material the scene does not know (its contacts keep the
/// obstacle's coefficient).
std::vector<double> FabricFriction(const SceneDescription& scene,
                                   const std::vector<GarmentRange>& garments, int num_particles) {
  std::vector<double> friction(num_particles, -1.0);
  for (std::size_t g = 0; g < garments.size() && g < scene.garments.size(); ++g) {
    double value = -1.0;
    try {
      value = ResolveMaterial(scene, scene.garments[g]).friction;
    } catch (const InputError&) {
      if (!scene.garments[g].model) throw;  // BuildGarment resolved it: cannot happen
    }
    std::fill_n(friction.begin() + garments[g].first_particle, garments[g].num_particles, value);
  }
  return friction;
}

/// Self-collision as the scene sets it (null when off: off costs nothing); the cloth keeps
/// the avatar's thickness off itself too, and rubs on itself with its fabrics' friction
/// (`fabric_friction`, FabricFriction's), none when the scene's friction is off.
std::unique_ptr<SelfCollision> MakeSelfCollision(const SceneDescription& scene,
                                                 std::shared_ptr<const ClothModel> model,
                                                 const std::vector<double>& fabric_friction) {
  if (!scene.effects.self_collision) return nullptr;
  SelfCollisionSettings self;
  if (scene.avatar) self.thickness = scene.avatar->thickness;
  if (scene.effects.friction) {
    self.particle_friction = fabric_friction;
  } else {
    self.friction = 0.0;
  }
  return std::make_unique<SelfCollision>(std::move(model), self);
}

}  // namespace

// Why the strain limit changes the rule: a step beyond kMaxStiffnessRatio injects energy by
// turning stiff springs through large angles along straight lines, the very stretch the
// strain limit takes back (strain_limit.h). With it the engine takes the steps it needs
// itself (StiffnessSteps), and only a model no kMaxSubsteps steps could run is refused;
// without it (the pure mass-spring model, for tests) a scene too stiff for its step is
// refused as before (tests/sim_core/scene/stability_matrix_test.cc runs both).
void RequireStableStepFor(const SceneDescription& scene, const ClothModel& model) {
  const double h = 1.0 / (scene.frame_rate * scene.solver.substeps);
  if (!(scene.solver.strain_limit > 0.0)) {
    RequireStableStep(model, h, scene.source);
    return;
  }
  const int steps = StepsForStiffness(model, 1.0 / scene.frame_rate, kMaxLimitedStiffnessRatio);
  if (steps > kMaxSubsteps) {
    throw InputError(scene.source + ": the stiffest spring on the lightest particle needs " +
                     std::to_string(steps) + " steps a frame (h²k/m <= " +
                     FormatValue(kMaxLimitedStiffnessRatio) + "), more than the " +
                     std::to_string(kMaxSubsteps) +
                     " allowed: use a softer material or heavier particles");
  }
}

std::shared_ptr<const ClothModel> BuildSceneModel(const SceneDescription& scene,
                                                  std::vector<GarmentRange>* garments,
                                                  std::vector<BodyAttachment>* attachments) {
  ClothModelData whole;
  whole.name = scene.name;
  for (const GarmentSpec& spec : scene.garments) {
    std::vector<BodyAttachment> own;
    const ClothModelData part = BuildGarment(scene, spec, own);
    for (BodyAttachment a : own) {
      a.particle += static_cast<int>(whole.masses.size());
      attachments->push_back(a);
    }
    garments->push_back({spec.name, static_cast<int>(whole.masses.size()),
                         static_cast<int>(part.masses.size()),
                         static_cast<int>(whole.triangles.size()),
                         static_cast<int>(part.triangles.size())});
    if (scene.garments.size() == 1) {
      whole = part;  // keeps the lattice shape, which the pyramid uses
    } else {
      Append(whole, part);
    }
  }
  return ClothModel::Create(std::move(whole));
}

int SolverThreads(int threads) {
  return threads == kMachineThreads ? ThreadPool::HardwareThreads() : threads;
}

std::unique_ptr<ThreadPool> MakeThreadPool(int threads) {
  const int n = SolverThreads(threads);
  return n > 1 ? std::make_unique<ThreadPool>(n) : nullptr;
}

StepperSettings StepperSettingsOf(const SceneDescription& scene) {
  StepperSettings settings;
  settings.method = scene.solver.method;
  settings.pcg.tolerance = scene.solver.tolerance;
  settings.pcg.max_iterations = scene.solver.max_iterations;
  settings.external.gravity = scene.gravity;
  settings.external.air_drag = scene.effects.air_drag;
  settings.levels = scene.solver.levels;
  settings.coarse_operator = scene.solver.coarse_operator;
  return settings;
}

std::unique_ptr<Simulation> Simulation::Build(const SceneDescription& scene,
                                              ArmSpreadMemo* arm_spreads,
                                              ColliderMemo* colliders) {
  ValidateScene(scene);
  std::vector<GarmentRange> garments;
  std::vector<BodyAttachment> attachments;
  auto model = BuildSceneModel(scene, &garments, &attachments);
  RequireStableStepFor(scene, *model);
  ArmSpreadMemo once;
  return std::unique_ptr<Simulation>(new Simulation(scene, std::move(model), std::move(garments),
                                                    std::move(attachments),
                                                    StepperSettingsOf(scene),
                                                    arm_spreads ? *arm_spreads : once, colliders));
}

Simulation::Simulation(SceneDescription scene, std::shared_ptr<const ClothModel> model,
                       std::vector<GarmentRange> garments, std::vector<BodyAttachment> attachments,
                       const StepperSettings& settings, ArmSpreadMemo& arm_spreads,
                       ColliderMemo* colliders)
    : scene_(std::move(scene)),
      model_(std::move(model)),
      garments_(std::move(garments)),
      pool_(MakeThreadPool(scene_.solver.threads)),
      pyramid_(MakePyramid(model_, settings)),
      stepper_(std::make_unique<ImplicitStepper>(
          model_, OnOwnThreads(settings), MakeStepSolver(*model_, OnOwnThreads(settings), pyramid_))),
      state_(ClothState::AtRest(*model_)),
      last_finite_(state_) {
  for (const SphereObstacleSpec& s : scene_.spheres) {
    spheres_.push_back({s.center, s.radius, s.thickness,
                        scene_.effects.friction ? s.friction : 0.0});
  }
  if (scene_.avatar) {
    const AvatarSpec& spec = *scene_.avatar;
    const AvatarMotionSettings motion = PlayedMotion(spec, arm_spreads, arm_spread_);
    avatar_ = std::make_unique<AvatarMotion>(spec.avatar, spec.clip, motion);
    attachments_ = std::move(attachments);
  }
  fabric_friction_ = FabricFriction(scene_, garments_, model_->num_particles());
  pinned_in_room_ = PinnedInRoom(*model_, attachments_);
  self_collision_ = MakeSelfCollision(scene_, model_, fabric_friction_);
  if (self_collision_) start_positions_ = state_.positions;
  BuildStrainLimiter();
  stiffness_steps_ = StiffnessSteps();
  contacts_.reserve(model_->num_particles());
  normal_impulse_.assign(model_->num_particles(), 0.0);
  // Last, as nothing may throw after it: a collider the memo kept is the one the simulation
  // built before is still stepping with, and moving it here would move that one's body too.
  if (avatar_) body_ = MakeAvatarCollider(scene_, *avatar_, step(), colliders);
}

int Simulation::num_frames() const {
  return static_cast<int>(std::lround(scene_.duration * scene_.frame_rate));
}

// A contact constraint prescribes the normal velocity, so it can pull as well as push, and
// it can push where nothing needs pushing. Released, unless the particle would now cross the
// shell within the step on its own velocity:
// - one that pulled in the last step (negative impulse: the cloth wants to lift off); kept,
//   it would glue cloth to the obstacle and freeze stretch into it;
// - one that pushed while its particle was clear of the shell (by more than kClearOfShell):
//   outside the shell a contact holds the particle's own predicted normal velocity
//   (ContactNormalVelocity), and where the skin faces down (the hips below their widest) that
//   prediction carries gravity's outward share, g·n, so the constraint pushed the skirt off
//   the hips, 4 mm/s faster every step, until it left the margin and its springs threw it
//   back (on a standing body the skirt's hips kept moving at up to 11 cm/s). What still keeps
//   a garment from settling is the solve's, docs/cloth_model.md "Limits at rest".
void Simulation::ReleaseAdhesiveContacts(double h) {
  constexpr double kClearOfShell = 1e-4;  // m: a tenth of a millimetre off the shell
  std::erase_if(contacts_, [this, h](const Contact& c) {
    const Eigen::Vector3d x = state_.positions.row(c.particle).transpose();
    const double normal_velocity = state_.velocities.row(c.particle).dot(c.normal);
    const double impulse = normal_impulse_[c.particle];
    if (!std::isfinite(c.shell_offset)) {
      return impulse < 0.0 && !(normal_velocity < c.target_normal_velocity);
    }
    const double gap = c.normal.dot(x) - c.shell_offset;
    const bool would_cross = gap + h * normal_velocity < 0.0;
    return !would_cross && (impulse < 0.0 || (impulse > 0.0 && gap > kClearOfShell));
  });
  // The stepper takes the impulse over this step's h for the last step's normal force.
  const double rescale = last_step_ > 0.0 ? h / last_step_ : 1.0;
  for (Contact& c : contacts_) {
    c.previous_normal_impulse = std::max(normal_impulse_[c.particle], 0.0) * rescale;
  }
}

void Simulation::BuildStrainLimiter() {
  strain_limiter_ =
      scene_.solver.strain_limit > 0.0 ? std::make_unique<StrainLimiter>(*model_) : nullptr;
}

StrainLimitSettings Simulation::StrainLimitOf() const {
  StrainLimitSettings settings;
  settings.limit = scene_.solver.strain_limit;
  return settings;
}

// Why the obstacles' corrections are tried first: the sweeps keep contacts outside their
// shells, but cloth that had no contact can end the step inside (a swinging leg under the
// hem), and the correction would then push it out alone, stretching its springs (up to
// 20 % on the walking skirt in cotton). Where the corrections would move cloth, the planes
// they would move it to are held in a second round of sweeps, so the correction after it
// finds little to do (docs/cloth_model.md, "Strain limiting").
void Simulation::ApplyStrainLimit(FrameReport& report) {
  const StrainLimitSettings settings = StrainLimitOf();
  strain_limiter_->SetTargets(*model_, settings, state_.positions);
  strain_limiter_->AddPlanes(contacts_);
  report.strain_corrections += strain_limiter_->Limit(*model_, settings, state_).corrections;
  if (spheres_.empty() && !body_) return;
  corrected_positions_ = state_.positions;  // same sizes every step: copy without allocating
  corrected_velocities_ = state_.velocities;
  for (const SphereObstacle& sphere : spheres_) {
    ProjectOutOfSphere(sphere, corrected_positions_, corrected_velocities_);
  }
  if (body_) {
    const auto start = std::chrono::steady_clock::now();
    body_->ProjectOut(corrected_positions_, corrected_velocities_);
    NoteWhatTheBodyLeftAlone();
    collision_in_limit_ms_ += MillisecondsSince(start);
  }
  correction_planes_.clear();
  for (Eigen::Index i = 0; i < state_.positions.rows(); ++i) {
    const Eigen::Vector3d move =
        (corrected_positions_.row(i) - state_.positions.row(i)).transpose();
    const double length = move.norm();
    if (!(length > kNoMove) || model_->is_pinned()[i]) continue;
    const Eigen::Vector3d normal = move / length;
    correction_planes_.push_back(
        {static_cast<int>(i), normal, normal.dot(corrected_positions_.row(i).transpose())});
  }
  if (correction_planes_.empty()) return;
  strain_limiter_->AddPlanes(correction_planes_);
  report.strain_corrections += strain_limiter_->Limit(*model_, settings, state_).corrections;
}

// The avatar moves to where it will be at the end of the step first, so contacts target the
// body's new surface and attached particles land where the body takes them.
void Simulation::MoveAvatar(double t, double h, bool posed, FrameReport& report) {
  const double blend = PostureBlendAfter(h);
  if (blend >= 1.0) posture_duration_ = 0.0;
  if (!posed) avatar_->Evaluate(t, blend);
  const auto start = std::chrono::steady_clock::now();
  body_->Update(avatar_->joint_world(), avatar_->vertices(), h);
  report.collision_update_ms += MillisecondsSince(start);
  for (const BodyAttachment& a : attachments_) {
    const Eigen::Vector3d target = avatar_->joint_world()[a.joint] * a.local;
    stepper_->SetPinVelocity(a.particle,
                            (target - state_.positions.row(a.particle).transpose()) / h);
  }
}

// Why the body's contacts are judged by the velocity gravity alone would give within the
// step: a contact outside the shell holds the particle's normal velocity rather than pull it
// in (ContactNormalVelocity), so judged by the start velocity, cloth let go at rest within
// the margin hovered there, held against gravity (2.1 mm over a sphere), and cloth tossed off
// the head rose twice as high as in free space (contact_release_test). The sphere keeps the
// landing target and the start velocity (docs/collision.md, "Contacts that pulled").
void Simulation::FindContacts(double h, FrameReport& report) {
  contacts_.clear();
  for (const SphereObstacle& sphere : spheres_) {
    // Contacts are caught half a thickness early so resting cloth stays constrained.
    FindSphereContacts(sphere, state_.positions, state_.velocities, h, 0.5 * sphere.thickness,
                       contacts_);
  }
  if (body_) {
    coasting_ = state_.velocities.rowwise() + h * scene_.gravity.transpose();
    const auto start = std::chrono::steady_clock::now();
    body_->FindContacts(state_.positions, coasting_, h, 0.5 * scene_.avatar->thickness,
                        contacts_);
    report.collision_ms += MillisecondsSince(start);
  }
  for (Contact& contact : contacts_) {
    const double fabric = fabric_friction_[contact.particle];
    if (fabric >= 0.0) contact.friction = MixFriction(fabric, contact.friction);
  }
}

double Simulation::AvatarTimeAfter(double dt) const {
  // lag 0 (never frozen) gives state_.time + dt bit for bit: the unfrozen run is unchanged.
  return avatar_frozen_ ? frozen_avatar_time_ : state_.time + dt - avatar_lag_;
}

double Simulation::PostureBlendAfter(double dt) const {
  if (!(posture_duration_ > 0.0)) return 1.0;  // no transition: exactly the pose at the time
  return std::min(1.0, (state_.time + dt - posture_start_) / posture_duration_);
}

int Simulation::StiffnessSteps() const {
  if (!strain_limiter_) return 1;  // RequireStableStepFor refused what one step cannot run
  return StepsForStiffness(*model_, 1.0 / scene_.frame_rate, kMaxLimitedStiffnessRatio);
}

int Simulation::StepsThisFrame(bool& posed_at_end) {
  posed_at_end = false;
  const int steps = std::max(scene_.solver.substeps, stiffness_steps_);
  if (!avatar_ || !(scene_.avatar->max_skin_travel > 0.0)) return steps;
  const AvatarSpec& spec = *scene_.avatar;
  const double frame = 1.0 / scene_.frame_rate;
  frame_start_skin_ = avatar_->vertices();
  const Eigen::Vector3d root = avatar_->joint_world()[0].translation();  // joint 0 is a root
  avatar_->Evaluate(AvatarTimeAfter(frame), PostureBlendAfter(frame));
  posed_at_end = true;
  // Cloth hanging from the body goes where its root takes it; cloth pinned in the room
  // does not, and meets a body walking into it at the walk's speed too.
  const Eigen::Vector3d root_shift =
      pinned_in_room_ ? Eigen::Vector3d::Zero()
                      : Eigen::Vector3d(avatar_->joint_world()[0].translation() - root);
  const double travel = SkinTravelNearCloth(frame_start_skin_, avatar_->vertices(), root_shift,
                                            state_.positions, spec.thickness);
  const double needed = std::ceil(travel / spec.max_skin_travel);
  const int most = std::max(steps, spec.max_steps_per_frame);
  return needed >= most ? most : std::max(steps, static_cast<int>(needed));
}

void Simulation::StepOnce(double h, bool avatar_posed, FrameReport& report) {
  if (avatar_) MoveAvatar(AvatarTimeAfter(h), h, avatar_posed, report);
  if (grabbing_) UpdateGrabForces();
  FindContacts(h, report);
  ReleaseAdhesiveContacts(h);
  if (self_collision_) start_positions_ = state_.positions;
  if (strain_limiter_) strain_limiter_->BeginStep(state_.positions);
  const auto solve_start = std::chrono::steady_clock::now();
  const StepReport step_report = stepper_->Step(state_, h, contacts_);
  report.solve_ms += MillisecondsSince(solve_start);
  report.steps += 1;
  report.iterations += step_report.iterations;
  report.coarse_iterations += step_report.coarse_iterations;
  report.converged = report.converged && step_report.converged;
  report.rolled_back_steps += step_report.rolled_back ? 1 : 0;
  report.num_contacts += step_report.num_contacts;
  if (step_report.rolled_back) {
    KeepFinite(/*stepper_rolled_back=*/true, report);
    return;
  }
  CorrectAfterSolve(h, report);
  if (!KeepFinite(/*stepper_rolled_back=*/false, report)) return;
  // Friction's memory of this step, for the next one: only from a step that stands (an
  // undone step's contacts hold no impulse, and the next step would slide without friction).
  std::fill(normal_impulse_.begin(), normal_impulse_.end(), 0.0);
  for (const Contact& c : contacts_) normal_impulse_[c.particle] = c.normal_impulse;
  last_step_ = h;
}

void Simulation::CorrectAfterSolve(double h, FrameReport& report) {
  body_saw_this_step_ = false;
  if (strain_limiter_) {
    const auto start = std::chrono::steady_clock::now();
    collision_in_limit_ms_ = 0.0;
    ApplyStrainLimit(report);
    report.strain_limit_ms += MillisecondsSince(start) - collision_in_limit_ms_;
    report.collision_ms += collision_in_limit_ms_;
  }
  for (const SphereObstacle& sphere : spheres_) {
    report.max_penetration = std::max(
        report.max_penetration, ProjectOutOfSphere(sphere, state_.positions, state_.velocities));
  }
  if (body_) {
    const auto start = std::chrono::steady_clock::now();
    ProjectOutOfBody(report);
    report.collision_ms += MillisecondsSince(start);
  }
  if (grabbing_) grab_feedback_ = GrabFeedback(*model_, state_, grabbed_, is_grabbed_);
  if (self_collision_) {
    const auto start = std::chrono::steady_clock::now();
    CollectBodyHolds();
    const SelfCollisionReport self =
        self_collision_->Resolve(start_positions_, h, state_, body_holds_);
    report.unresolved_self_collisions += self.remaining_collisions;
    LimitWhatSelfCollisionStretched(h, report);
    if (body_) ResolveWhatTheBodyMovesBack(h, report);
    report.self_collision_ms += MillisecondsSince(start);
  }
  if (body_) AddBodyStats(report);
}

void Simulation::ProjectOutOfBody(FrameReport& report) {
  if (self_collision_) solved_positions_ = state_.positions;
  const double depth =
      body_saw_this_step_
          ? body_->ProjectOut(state_.positions, state_.velocities, NeedingBodyCorrection())
          : body_->ProjectOut(state_.positions, state_.velocities);
  report.max_penetration = std::max(report.max_penetration, depth);
  PlaceAttachments();
}

// Why a particle left alone needs no second look: the correction reads only its position
// and the body, which has not moved since, so it would leave it alone again. Two full
// corrections a step took 14 ms of a 48 ms frame on a 2,000-particle suit. Where it was
// seen is still in corrected_positions_ (left alone: unchanged there).
void Simulation::NoteWhatTheBodyLeftAlone() {
  const auto n = static_cast<std::size_t>(state_.positions.rows());
  body_left_alone_.resize(n);
  body_recheck_.reserve(n);  // so NeedingBodyCorrection never allocates after the first step
  for (Eigen::Index i = 0; i < state_.positions.rows(); ++i) {
    body_left_alone_[i] = corrected_positions_.row(i) == state_.positions.row(i) &&
                          corrected_velocities_.row(i) == state_.velocities.row(i);
  }
  body_saw_this_step_ = true;
}

const std::vector<int>& Simulation::NeedingBodyCorrection() {
  body_recheck_.clear();
  for (Eigen::Index i = 0; i < state_.positions.rows(); ++i) {
    if (!body_left_alone_[i] || state_.positions.row(i) != corrected_positions_.row(i)) {
      body_recheck_.push_back(static_cast<int>(i));
    }
  }
  return body_recheck_;
}

// Attached particles are where the body puts them; the correction must not move them.
void Simulation::PlaceAttachments() {
  for (const BodyAttachment& a : attachments_) {
    state_.positions.row(a.particle) = (avatar_->joint_world()[a.joint] * a.local).transpose();
  }
}

// Why the strain limit again: self-collision acts after the solve, so no spring spreads its
// impulses. Stopping a fast layer against another drags the other's particles along while
// their neighbours stay (MakeHuman's suit kicking: a particle 35 mm in one step, the frames'
// largest strain 200 %). So the strain limit (Provot 1995) runs after the collision response
// too, and the path of its correction is made crossing-free again. Only crossing-free:
// ResolveMove's push-out to the thickness stretched the springs the limit had just
// shortened. The stops of ResolveCrossings can stretch a few springs again, hence another
// round when it stopped anything. The cap alone here (StrainLimiter::SetCapTargets): cut
// back to the lengths the step meant, the impulses' own moves were undone, and a patch
// held by friction on a sheet crept at 2.8 mm/s where it creeps at 0.7–1.4.
void Simulation::LimitWhatSelfCollisionStretched(double h, FrameReport& report) {
  if (!strain_limiter_) return;
  constexpr int kRounds = 4;
  strain_limiter_->SetCapTargets(*model_, StrainLimitOf());
  for (int round = 0; round < kRounds; ++round) {
    self_resolved_ = state_.positions;  // same size every step: copies without allocating
    const int corrections = strain_limiter_->Limit(*model_, StrainLimitOf(), state_).corrections;
    report.strain_corrections += corrections;
    if (corrections == 0) return;  // nothing moved: nothing to resolve
    const SelfCollisionReport again =
        self_collision_->ResolveCrossings(self_resolved_, h, state_, body_holds_);
    report.unresolved_self_collisions += again.remaining_collisions;
    if (again.collision_impulses == 0 && again.zone_particles == 0) return;  // crossed nothing
  }
}

// Why a second correction and a second Resolve: self-collision's impulses push cloth into
// the body (a neighbouring layer's edge threw the walking cape's particle 1712 13.7 mm
// sideways, 4 mm into the skin, with no contact to hold it). Correcting once more leaves
// nothing inside, but alone it put 20-330 edges through the cloth; resolving that short
// path again, with the particles it moved held, leaves neither (docs/collision.md).
// Why the body then has the last word: where the body presses layers from both sides (an
// armpit, a thigh skinned through the groin), keeping them apart can only push one into
// the skin, and ResolveMove did (MakeHuman's suit kicking: 14.9 mm deep, 9.8 mm p99). Cloth
// through cloth there is hidden between the skins; cloth in the body is not. Only out of
// the skin, not onto the shell: pushed onto the shell, the walking cape at 90 around ended
// with 7 edges through itself; left within the thickness, with none.
void Simulation::ResolveWhatTheBodyMovesBack(double h, FrameReport& report) {
  ProjectOutOfBody(report);
  if (!HoldWhatTheBodyMoved()) return;
  before_move_ = state_.positions;  // same size every step: copies without allocating
  const SelfCollisionReport again =
      self_collision_->ResolveMove(solved_positions_, h, state_, body_holds_);
  report.unresolved_self_collisions += again.remaining_collisions;
  ProjectOutWhatResolveMoved(report);
}

void Simulation::ProjectOutWhatResolveMoved(FrameReport& report) {
  moved_by_resolve_.clear();
  for (Eigen::Index i = 0; i < state_.positions.rows(); ++i) {
    if ((state_.positions.row(i) - before_move_.row(i)).norm() > kNoMove) {
      moved_by_resolve_.push_back(static_cast<int>(i));
    }
  }
  if (moved_by_resolve_.empty()) return;
  const double skin_depth =
      body_->ProjectOutOfSkin(state_.positions, state_.velocities, moved_by_resolve_);
  if (skin_depth > 0.0) {  // reported, as the other corrections' depths are, below the shell
    report.max_penetration =
        std::max(report.max_penetration, skin_depth + scene_.avatar->thickness);
  }
  PlaceAttachments();
}

void Simulation::AddBodyStats(FrameReport& report) const {
  const BodyCollisionStats stats = body_->stats();  // summed since this step's FindContacts
  report.maps_drawn += stats.num_maps_drawn;
  report.maps_reused += stats.num_maps_reused;
  report.skin_checks += stats.num_skin_checks;
  report.winding_checks += stats.num_winding_checks;
  report.buried += stats.num_buried;
}

// Why the last step's contacts too: a traced particle of the walking dress lifting off the
// thigh had no contact in the step a falling layer landed on it, and the two, sharing the
// blow, went 10 mm into the thigh.
void Simulation::CollectBodyHolds() {
  body_holds_.clear();
  if (!body_) return;
  const int n = model_->num_particles();
  hold_of_.assign(n, -1);
  for (const Contact& c : contacts_) {
    if (hold_of_[c.particle] >= 0) continue;
    hold_of_[c.particle] = static_cast<int>(body_holds_.size());
    body_holds_.push_back({c.particle, c.normal});
  }
  for (const BodyHold& previous : previous_holds_) {
    if (previous.particle >= n || hold_of_[previous.particle] >= 0) continue;
    hold_of_[previous.particle] = static_cast<int>(body_holds_.size());
    body_holds_.push_back(previous);
  }
  HoldWhatTheBodyMoved();
  previous_holds_.clear();
  for (const Contact& c : contacts_) previous_holds_.push_back({c.particle, c.normal});
}

bool Simulation::HoldWhatTheBodyMoved() {
  bool any = false;
  for (Eigen::Index i = 0; i < state_.positions.rows(); ++i) {
    const Eigen::Vector3d moved = (state_.positions.row(i) - solved_positions_.row(i)).transpose();
    const double length = moved.norm();
    if (!(length > kNoMove)) continue;
    any = true;
    if (hold_of_[i] < 0) {
      hold_of_[i] = static_cast<int>(body_holds_.size());
      body_holds_.push_back({static_cast<int>(i), moved / length});
    } else {
      body_holds_[hold_of_[i]].normal = moved / length;
    }
  }
  return any;
}

bool Simulation::KeepFinite(bool stepper_rolled_back, FrameReport& report) {
  if (state_.positions.allFinite() && state_.velocities.allFinite()) {
    last_finite_ = state_;  // same sizes every step: copies without allocating
    return true;
  }
  // A clip whose root jumped 1e298 m for one frame put the attached particles there, and
  // the cloth never came back: each later step started from, and rolled back to, that state.
  state_ = last_finite_;
  if (!stepper_rolled_back) ++report.rolled_back_steps;
  if (grabbing_) grab_feedback_ = GrabFeedback(*model_, state_, grabbed_, is_grabbed_);
  return false;
}

bool Simulation::SetGrab(const Grab& grab) {
  if (!IsValidGrab(grab)) return false;
  grab_ = grab;
  if (!grabbing_) StartGrab();
  grabbing_ = true;
  ConnectGrab();
  return true;
}

void Simulation::ConnectGrab() {
  if (grabbing_ && grab_.coupling_stiffness > 0.0) {
    stepper_->SetAppliedForces(nullptr);
    stepper_->SetAnchors(&anchor_targets_, &anchor_stiffness_);
  } else if (grabbing_) {
    stepper_->SetAnchors(nullptr, nullptr);
    stepper_->SetAppliedForces(&applied_);
  } else {
    stepper_->SetAppliedForces(nullptr);
    stepper_->SetAnchors(nullptr, nullptr);
  }
}

void Simulation::ReleaseGrab() {
  grabbing_ = false;
  stepper_->SetAppliedForces(nullptr);
  stepper_->SetAnchors(nullptr, nullptr);
  grabbed_.clear();
  grab_feedback_.setZero();
}

// The selection and what a coupling grab keeps of its start: the grabbed particles' positions
// and Gaussian weights there, so the grab's shape travels with the sphere.
void Simulation::StartGrab() {
  SelectGrabbed(grab_, state_.positions, grabbed_);
  grab_start_centre_ = grab_.centre;
  grab_start_positions_.resize(static_cast<Eigen::Index>(grabbed_.size()), 3);
  grab_start_weights_.resize(grabbed_.size());
  for (std::size_t k = 0; k < grabbed_.size(); ++k) {
    grab_start_positions_.row(k) = state_.positions.row(grabbed_[k]);
    grab_start_weights_[k] = GrabWeight(grab_, grab_start_positions_.row(k).transpose());
  }
  anchor_targets_.setZero(model_->num_particles(), 3);
  anchor_stiffness_.setZero(model_->num_particles());
}

// A force grab applies F_h·g at the particles' current distance from the sphere; a coupling
// grab moves each grabbed particle's anchor with the sphere.
void Simulation::UpdateGrabForces() {
  if (grab_.coupling_stiffness <= 0.0) {
    ApplyGrab(grab_, state_.positions, grabbed_, applied_);
    return;
  }
  const Eigen::Vector3d moved = grab_.centre - grab_start_centre_;
  for (std::size_t k = 0; k < grabbed_.size(); ++k) {
    anchor_targets_.row(grabbed_[k]) = grab_start_positions_.row(k) + moved.transpose();
    anchor_stiffness_[grabbed_[k]] = grab_.coupling_stiffness * grab_start_weights_[k];
  }
}

int Simulation::EliminateStretchEnergy(const Eigen::Vector3d& centre, double radius) {
  if (!centre.allFinite() || !std::isfinite(radius) || radius <= 0.0) return 0;
  std::vector<int> region;
  std::vector<bool> inside(model_->num_particles(), false);
  for (int p = 0; p < model_->num_particles(); ++p) {
    if ((state_.positions.row(p).transpose() - centre).norm() > radius) continue;
    inside[p] = true;
    region.push_back(p);
  }
  Eigen::VectorXd rest(model_->num_springs());
  int changed = 0;
  for (int k = 0; k < model_->num_springs(); ++k) {
    const Spring& s = model_->springs()[k];
    rest[k] = s.rest_length;
    if (!inside[s.a] || !inside[s.b]) continue;
    const double length = (state_.positions.row(s.b) - state_.positions.row(s.a)).norm();
    if (!(length > 0.0) || !std::isfinite(length)) continue;  // collapsed: keeps its rest length
    rest[k] = length;
    ++changed;
  }
  if (changed == 0) return 0;
  undo_.push_back(pyramid_ ? pyramid_->LevelModels()
                           : std::vector<std::shared_ptr<const ClothModel>>{model_});
  model_ = model_->WithRestLengths(rest);
  stepper_->ReplaceModel(model_);
  if (pyramid_) pyramid_->UpdateRegion(model_, state_.positions, region);
  BuildStrainLimiter();  // the tethers' rest distances follow the edited rest lengths
  return changed;
}

bool Simulation::UndoEdit() {
  if (undo_.empty()) return false;
  const std::vector<std::shared_ptr<const ClothModel>> models = std::move(undo_.back());
  undo_.pop_back();
  model_ = models.front();
  BuildStrainLimiter();
  if (pyramid_ && static_cast<int>(models.size()) != pyramid_->num_levels()) {
    // Saved before a SetSolver (level 0 only): this solver's pyramid is rebuilt around it.
    BuildSolver(StepperSettingsOf(scene_));
    return true;
  }
  stepper_->ReplaceModel(model_);
  if (pyramid_) pyramid_->RestoreLevelModels(models);
  return true;
}

StepperSettings Simulation::OnOwnThreads(StepperSettings settings) const {
  settings.pcg.pool = pool_.get();
  return settings;
}

void Simulation::BuildSolver(const StepperSettings& own) {
  const StepperSettings settings = OnOwnThreads(own);
  auto pyramid = MakePyramid(model_, settings);
  auto stepper = std::make_unique<ImplicitStepper>(model_, settings,
                                                   MakeStepSolver(*model_, settings, pyramid));
  pyramid_ = std::move(pyramid);
  stepper_ = std::move(stepper);
  ConnectGrab();
}

// Only the solver changes: the state, the (edited) model, the grab and the avatar's clock
// stay. Pin velocities are set again before every step (MoveAvatar). The undo history keeps
// each revision's level-0 model; a pyramid's coarse levels are rebuilt from the current model
// now and from the restored one on an undo (rather than carried through the old pyramid).
void Simulation::SetSolver(const SolverSettings& solver) {
  SceneDescription scene = scene_;
  scene.solver = solver;
  ValidateScene(scene);  // throws before anything changes
  RequireStableStepFor(scene, *model_);
  // The old pool outlives the old stepper, which holds its address until replaced.
  std::unique_ptr<ThreadPool> old_pool;
  if (SolverThreads(scene.solver.threads) != SolverThreads(scene_.solver.threads)) {
    old_pool = std::exchange(pool_, MakeThreadPool(scene.solver.threads));
  }
  BuildSolver(StepperSettingsOf(scene));
  scene_ = std::move(scene);
  BuildStrainLimiter();
  stiffness_steps_ = StiffnessSteps();
  for (std::vector<std::shared_ptr<const ClothModel>>& revision : undo_) revision.resize(1);
}

void Simulation::SetCollision(const CollisionSettings& settings, ColliderMemo* colliders) {
  SceneDescription scene = scene_;
  ApplyCollisionSettings(settings, scene);
  ValidateScene(scene);  // throws before anything changes
  // Built before anything is replaced, so a failure leaves the old colliders in place.
  std::shared_ptr<BodyCollider> body;
  if (avatar_ && scene.avatar->collision != scene_.avatar->collision) {
    body = MakeAvatarCollider(scene, *avatar_, step(), colliders);
  }
  const bool self_changed =
      scene.effects.self_collision != scene_.effects.self_collision ||
      (scene.avatar && scene.avatar->thickness != scene_.avatar->thickness);
  std::unique_ptr<SelfCollision> self =
      self_changed ? MakeSelfCollision(scene, model_, fabric_friction_) : nullptr;
  // Map memory, thickness and friction change in place: nothing is fitted again for them
  // (a new collider was built with them). Before anything is replaced, as the store's
  // reservation is the one thing here that may fail.
  if (body_ && !body) {
    ApplyColliderSettings(*body_, ContactSettings(scene), scene.avatar->superquadric_map_mb);
  }
  if (body) body_ = std::move(body);
  if (self_changed) {
    self_collision_ = std::move(self);
    if (self_collision_) start_positions_ = state_.positions;
  }
  scene_ = std::move(scene);
}

bool Simulation::SetPosture(const Pose& posture, double transition_time,
                            const ArmSpreadRequest& spread, ArmSpreadMemo* arm_spreads) {
  if (!avatar_) return false;
  if (!(transition_time >= 0.0) || !std::isfinite(transition_time)) {
    throw InputError(scene_.source + ": posture transition_time = " +
                     std::to_string(transition_time) + " s: must be finite and >= 0");
  }
  AvatarSpec posed = WithPosture(*scene_.avatar, posture, spread);
  ArmSpreadMemo once;
  ArmSpreadFit fit =
      SpreadForPosture(posed, spread, arm_spread_, arm_spreads ? *arm_spreads : once);
  avatar_->SetPosture(posture, fit.angle);  // throws before anything changes
  *scene_.avatar = std::move(posed);
  arm_spread_ = std::move(fit);
  posture_start_ = state_.time;
  posture_duration_ = transition_time;
  return true;
}

void Simulation::SetAvatarFrozen(bool frozen) {
  if (frozen == avatar_frozen_) return;
  if (frozen) {
    frozen_avatar_time_ = avatar_time();
  } else {
    avatar_lag_ = state_.time - frozen_avatar_time_;
  }
  avatar_frozen_ = frozen;
}

double Simulation::avatar_time() const {
  return avatar_frozen_ ? frozen_avatar_time_ : state_.time - avatar_lag_;
}

FrameReport Simulation::AdvanceFrame() {
  const auto start = std::chrono::steady_clock::now();
  FrameReport report;
  bool posed_at_end = false;
  const int steps = StepsThisFrame(posed_at_end);
  // Unsplit, h is step() bit for bit, and a single step ends where the measure posed the
  // avatar (the same time and blend), so it is not skinned twice.
  const double h = 1.0 / (scene_.frame_rate * steps);
  for (int s = 0; s < steps; ++s) StepOnce(h, posed_at_end && steps == 1, report);
  report.wall_ms = MillisecondsSince(start);
  return report;
}

}  // namespace costume::sim
