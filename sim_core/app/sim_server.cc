#include "sim_core/app/sim_server.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <ctime>
#include <optional>
#include <sstream>
#include <utility>

#include "bus/channels.h"
#include "bus/settings_codec.h"
#include "sim_core/avatar/hanim.h"
#include "sim_core/avatar/pose.h"
#include "sim_core/common/input_error.h"
#include "sim_core/common/monotonic_clock.h"
#include "sim_core/common/percentile.h"

namespace costume::sim_app {

namespace {

using sim::kNanosPerSecond;
/// Pending warnings kept for one status message; later ones in the same period are dropped
/// (and the last entry says so) so a flood of bad commands cannot grow the message.
constexpr std::size_t kMaxWarnings = 16;
constexpr int kGrabButton = 1;  // grab.buttons bit 0

sim::Grab ToGrab(const costume_lcm::grab& message) {
  sim::Grab grab;
  grab.centre = Eigen::Vector3d(message.centre[0], message.centre[1], message.centre[2]);
  grab.radius = message.radius;
  grab.force = Eigen::Vector3d(message.force[0], message.force[1], message.force[2]);
  grab.coupling_stiffness = message.coupling_stiffness;
  return grab;
}

std::int8_t ToLcmMode(Mode mode) {
  return mode == Mode::kEditing ? costume_lcm::status::MODE_EDITING
                                : costume_lcm::status::MODE_ANIMATION;
}

std::int8_t ToLcmPlayback(Playback playback) {
  switch (playback) {
    case Playback::kPlaying: return costume_lcm::status::PLAYBACK_PLAYING;
    case Playback::kPaused: return costume_lcm::status::PLAYBACK_PAUSED;
    case Playback::kStopped: break;
  }
  return costume_lcm::status::PLAYBACK_STOPPED;
}

std::string CommandName(std::int8_t kind) {
  using C = costume_lcm::command;
  switch (kind) {
    case C::KIND_LOAD_AVATAR: return "LOAD_AVATAR";
    case C::KIND_LOAD_COSTUME: return "LOAD_COSTUME";
    case C::KIND_LOAD_ANIMATION: return "LOAD_ANIMATION";
    case C::KIND_SET_MATERIAL: return "SET_MATERIAL";
    case C::KIND_SAVE_VERSION: return "SAVE_VERSION";
    default: return "kind " + std::to_string(kind);
  }
}

}  // namespace

PeriodFigures ComputePeriodFigures(std::vector<std::int64_t>& periods) {
  PeriodFigures figures;
  if (periods.empty()) return figures;
  std::sort(periods.begin(), periods.end());
  const auto n = static_cast<std::int64_t>(periods.size());
  auto us = [&](double q) {
    return 1e-3 * static_cast<double>(sim::NearestRankPercentile(periods.data(), n, q));
  };
  figures.p50_us = us(0.50);
  figures.p99_us = us(0.99);
  figures.p999_us = us(0.999);
  figures.max_us = 1e-3 * static_cast<double>(periods.back());
  return figures;
}

Deadline NextDeadline(std::int64_t deadline, std::int64_t now, std::int64_t period) {
  Deadline result{deadline + period, 0};
  if (period <= 0 || result.next >= now) return result;
  // The frame ran past its successor's deadline: jump to the first one still ahead.
  const std::int64_t behind = (now - result.next) / period + 1;
  result.next += behind * period;
  result.missed = behind;
  return result;
}

SimServer::SimServer(bus::MessageBus& bus, sim::SceneDescription scene, SimServerOptions options)
    : bus_(bus),
      scene_(std::move(scene)),
      options_(std::move(options)),
      frame_publisher_(bus, bus::kClothFrameChannel),
      patch_publisher_(bus, bus::kHapticPatchChannel),
      status_publisher_(bus, bus::kSimStatusChannel) {
  if (!(options_.status_period > 0.0) || !(options_.grab_timeout > 0.0)) {
    throw sim::InputError("SimServerOptions: status_period = " +
                          std::to_string(options_.status_period) + " s, grab_timeout = " +
                          std::to_string(options_.grab_timeout) + " s: both must be > 0");
  }
  if (!(options_.posture_transition >= 0.0) || !std::isfinite(options_.posture_transition)) {
    throw sim::InputError("SimServerOptions: posture_transition = " +
                          std::to_string(options_.posture_transition) + " s: must be >= 0");
  }
  Rebuild(scene_);
  mode_ = options_.mode;
  SetMode(options_.mode);
  playback_ = options_.start_playing ? Playback::kPlaying : Playback::kStopped;
  commands_.reserve(16);
  // Each input's seq is kept and stamped on the frames it fed (cloth_frame.grab_seq, ...),
  // so a recorded session can be replayed frame for frame (tools/replay.cc).
  command_counts_ = bus::Subscribe<costume_lcm::command>(
      bus_, bus::kCommandChannel,
      [this](const costume_lcm::command& c) {
        commands_.push_back(c);
        command_seq_ = c.seq;
      },
      options_.receive_policy);
  haptic_command_counts_ = bus::Subscribe<costume_lcm::command>(
      bus_, bus::kHapticCommandChannel,
      [this](const costume_lcm::command& c) {
        commands_.push_back(c);
        haptic_command_seq_ = c.seq;
      },
      options_.receive_policy);
  grab_counts_ = bus::Subscribe<costume_lcm::grab>(
      bus_, bus::kGrabChannel,
      [this](const costume_lcm::grab& g) {
        latest_grab_ = g;
        has_new_grab_ = true;
        grab_seq_ = g.seq;
      },
      options_.receive_policy);
  // Room for four status periods of frames, so a late status loses none; never grown.
  frame_periods_.reserve(static_cast<std::size_t>(
      std::clamp(4.0 * options_.status_period * scene_.frame_rate, 64.0, 1e6)));
  period_start_ = std::chrono::steady_clock::now();
}

bus::ReceiveCounts SimServer::command_counts() const {
  bus::ReceiveCounts sum = *command_counts_;
  const bus::ReceiveCounts& h = *haptic_command_counts_;
  sum.accepted += h.accepted;
  sum.malformed += h.malformed;
  sum.oversized += h.oversized;
  sum.stale += h.stale;
  sum.out_of_order += h.out_of_order;
  sum.sender_restarts += h.sender_restarts;
  return sum;
}

void SimServer::Warn(std::string warning) {
  if (warnings_.size() + 1 < kMaxWarnings) {
    warnings_.push_back(std::move(warning));
  } else if (warnings_.size() + 1 == kMaxWarnings) {
    warnings_.push_back("more warnings this period were dropped");
  }
}

// ---- the frame ---------------------------------------------------------------------------

void SimServer::Step() {
  const auto start = std::chrono::steady_clock::now();
  bus_.HandleSubscriptions(0);
  for (const costume_lcm::command& command : commands_) ApplyCommand(command);
  commands_.clear();
  ApplyLatestGrab();
  if (playback_ == Playback::kPlaying) {
    const sim::FrameReport report = simulation_->AdvanceFrame();
    last_iterations_ = report.iterations;
    period_unconverged_frames_ += report.converged ? 0 : 1;
    period_rolled_back_steps_ += report.rolled_back_steps;
    ++frame_;
  }
  PublishFrame();
  if (grabbing()) PublishPatch();
  ++ticks_;
  const double work_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  PublishStatusIfDue(work_ms);
}

std::int64_t SimServer::Run(const std::atomic<bool>& stop, std::int64_t max_frames) {
  const auto period = static_cast<std::int64_t>(std::llround(1e9 / scene_.frame_rate));
  const auto now = options_.clock_now ? options_.clock_now : sim::MonotonicNs;
  const auto sleep_until = options_.clock_sleep_until
                               ? options_.clock_sleep_until
                               : std::function<void(std::int64_t)>(sim::SleepUntilNs);
  std::int64_t deadline = now();
  std::int64_t previous_wake = -1;
  std::int64_t steps = 0;
  while (!stop.load(std::memory_order_relaxed) && (max_frames <= 0 || steps < max_frames)) {
    const std::int64_t wake = now();
    if (previous_wake >= 0 && frame_periods_.size() < frame_periods_.capacity()) {
      frame_periods_.push_back(wake - previous_wake);
    }
    previous_wake = wake;
    Step();
    ++steps;
    const Deadline next = NextDeadline(deadline, now(), period);
    overruns_ += next.missed;
    deadline = next.next;
    sleep_until(deadline);
  }
  return steps;
}

void SimServer::Rebuild(const sim::SceneDescription& scene) {
  // Throws before anything changes.
  auto rebuilt = sim::Simulation::Build(scene, &arm_spreads_, &colliders_);
  if (grabbing()) ReleaseGrab();
  simulation_ = std::move(rebuilt);
  simulation_->SetAvatarFrozen(mode_ == Mode::kEditing);
  scene_ = scene;
  frame_ = 0;
  ++model_revision_;  // a fresh model: patches of the old one must not be mistaken for it
  edits_.clear();
  redo_.clear();
  patch_slot_.assign(simulation_->model().num_particles(), -1);
}

// ---- commands ----------------------------------------------------------------------------

void SimServer::ApplyCommand(const costume_lcm::command& command) {
  using C = costume_lcm::command;
  switch (command.kind) {
    case C::KIND_SET_MODE:
      if (command.mode == C::MODE_ANIMATION || command.mode == C::MODE_EDITING) {
        SetMode(command.mode == C::MODE_EDITING ? Mode::kEditing : Mode::kAnimation);
      } else {
        ++ignored_.commands_refused;
        Warn("command SET_MODE: mode = " + std::to_string(command.mode) +
             ": must be 0 (animation) or 1 (editing)");
      }
      return;
    case C::KIND_PLAY: playback_ = Playback::kPlaying; return;
    case C::KIND_PAUSE:
      if (playback_ == Playback::kPlaying) playback_ = Playback::kPaused;
      return;
    case C::KIND_STOP:
      try {
        Rebuild(scene_);  // built once already, so not expected to throw
      } catch (const sim::InputError& error) {
        Warn(std::string("command STOP: rebuild failed: ") + error.what());
      }
      playback_ = Playback::kStopped;
      return;
    case C::KIND_ELIMINATE_STRETCH: EliminateStretch(command); return;
    case C::KIND_UNDO: Undo(); return;
    case C::KIND_REDO: Redo(); return;
    case C::KIND_SET_SOLVER: SetSolver(command.solver); return;
    case C::KIND_SET_COLLISION: SetCollision(command.collision); return;
    case C::KIND_SET_POSTURE: SetPosture(command); return;
    case C::KIND_LOAD_AVATAR: Load(LoadKind::kAvatar, command); return;
    case C::KIND_LOAD_COSTUME: Load(LoadKind::kCostume, command); return;
    case C::KIND_LOAD_ANIMATION: Load(LoadKind::kAnimation, command); return;
    case C::KIND_SET_MATERIAL: SetMaterial(command); return;
    case C::KIND_SAVE_VERSION: SaveVersion(command); return;
    case C::KIND_SET_SELECTION_RADIUS: return;  // the haptic server's (the grab's radius)
    default:
      ++ignored_.commands_refused;
      Warn("command kind = " + std::to_string(command.kind) + ": unknown (1 to 16); ignored");
  }
}

void SimServer::SetMode(Mode mode) {
  mode_ = mode;
  simulation_->SetAvatarFrozen(mode == Mode::kEditing);
  if (mode == Mode::kAnimation && grabbing()) ReleaseGrab();  // modes are exclusive
}

void SimServer::EliminateStretch(const costume_lcm::command& command) {
  SphereEdit edit{Eigen::Vector3d(command.centre[0], command.centre[1], command.centre[2]),
                  command.radius};
  if (command.grab_id >= 0 && grabbing() && command.grab_id == grab_id_) {
    const sim::Grab& held = simulation_->grab();  // the sphere the designer holds
    edit = {held.centre, held.radius};
  } else if (command.grab_id >= 0) {
    Warn("command ELIMINATE_STRETCH: grab_id = " + std::to_string(command.grab_id) +
         " is not the active grab (" + std::to_string(active_grab_id()) +
         "); using the command's sphere");
  }
  if (!edit.centre.allFinite() || !std::isfinite(edit.radius) || edit.radius <= 0.0) {
    ++ignored_.commands_refused;
    Warn("command ELIMINATE_STRETCH: radius = " + std::to_string(edit.radius) +
         " m or a centre coordinate is not finite: radius must be > 0; ignored");
    return;
  }
  if (simulation_->EliminateStretchEnergy(edit.centre, edit.radius) == 0) {
    Warn("command ELIMINATE_STRETCH: no spring has both ends in the sphere; nothing changed");
    return;
  }
  edits_.push_back(edit);
  redo_.clear();
  ++model_revision_;
}

void SimServer::Undo() {
  if (!simulation_->UndoEdit()) {
    Warn("command UNDO: nothing to undo");
    return;
  }
  if (!edits_.empty()) {
    redo_.push_back(edits_.back());
    edits_.pop_back();
  }
  ++model_revision_;
}

// Re-applies the undone sphere edit at the cloth's current shape: exact when the cloth has
// not moved since the undo, an approximation otherwise (the edit stores the sphere, not the
// rest lengths; docs/processes.md).
void SimServer::Redo() {
  if (redo_.empty()) {
    Warn("command REDO: nothing to redo");
    return;
  }
  const SphereEdit edit = redo_.back();
  redo_.pop_back();
  if (simulation_->EliminateStretchEnergy(edit.centre, edit.radius) == 0) {
    Warn("command REDO: no spring has both ends in the sphere any more; nothing changed");
    return;
  }
  edits_.push_back(edit);
  ++model_revision_;
}

// Only the solver changes (Simulation::SetSolver): the cloth state, the edited rest lengths,
// the undo and redo history, the held grab, the frame number and the avatar's clock stay;
// the model revision too (same springs, same rest lengths).
void SimServer::SetSolver(const costume_lcm::solver_parameters& solver) {
  try {
    const sim::SolverSettings settings = bus::FromMessage(solver);
    simulation_->SetSolver(settings);
    scene_.solver = settings;
  } catch (const sim::InputError& error) {
    ++ignored_.commands_refused;
    Warn(std::string("command SET_SOLVER refused, solver unchanged: ") + error.what());
  }
}

// Only how cloth collides changes (Simulation::SetCollision), as with SET_SOLVER: the state,
// the edits and their history, the grab, the frame number and the avatar's clock stay.
void SimServer::SetCollision(const costume_lcm::collision_parameters& collision) {
  try {
    const sim::CollisionSettings settings = bus::FromMessage(collision);
    simulation_->SetCollision(settings, &colliders_);
    sim::ApplyCollisionSettings(settings, scene_);
    if (!scene_.avatar) {
      Warn("command SET_COLLISION: the scene has no avatar; only self_collision applied");
    }
  } catch (const sim::InputError& error) {
    ++ignored_.commands_refused;
    Warn(std::string("command SET_COLLISION refused, collision unchanged: ") + error.what());
  }
}

// ---- the catalogue ---------------------------------------------------------------------

SceneCatalog* SimServer::OpenCatalog(const std::string& command_name) {
  if (catalog_) return catalog_.get();
  if (!options_.open_catalog) {
    Warn("command " + command_name + ": the server was started without a catalogue; ignored");
    return nullptr;
  }
  try {
    catalog_ = options_.open_catalog();
  } catch (const std::exception& error) {  // InputError, or a library's own
    Warn("command " + command_name + ": the catalogue " + options_.catalog_url +
         " could not be opened (" + error.what() + "); ignored");
    return nullptr;
  }
  return catalog_.get();
}

// The scene with the entry in it is built first; only when that succeeds does it replace the
// running simulation (back to frame 0, as STOP), keeping mode and playback.
void SimServer::Load(LoadKind kind, const costume_lcm::command& command) {
  const std::string name = CommandName(command.kind);
  SceneCatalog* catalog = OpenCatalog(name);
  if (catalog == nullptr) {
    ++ignored_.commands_refused;
    return;
  }
  const std::shared_ptr<const sim::Avatar> avatar_before =
      scene_.avatar ? scene_.avatar->avatar : nullptr;
  sim::SceneDescription scene = scene_;
  try {
    const std::string entry = catalog->Load(kind, command.database_id, command.name, scene);
    try {
      Rebuild(scene);
    } catch (const sim::InputError& error) {
      throw sim::InputError(entry + " cannot be simulated: " + error.what());
    }
    // A costume made for one body (a MakeHuman garment) brings that body: say so, as the
    // designer picked a costume, not an avatar.
    if (kind == LoadKind::kCostume && avatar_before && scene_.avatar &&
        scene_.avatar->avatar != avatar_before) {
      Warn("loaded " + entry + " on the body it is made for: the avatar is now '" +
           scene_.avatar->avatar->name() + "'");
    }
    // The clip plays with its arms turned out (arm_spread.h): the designer sees a motion
    // other than the file's, so say by how much and why.
    const sim::ArmSpreadFit& spread = simulation_->arm_spread();
    if (spread.measured && (spread.angle[0] > 0.0 || spread.angle[1] > 0.0)) {
      Warn("loaded " + entry + ": " + sim::DescribeArmSpread(spread));
    }
  } catch (const std::exception& error) {
    ++ignored_.commands_refused;
    Warn("command " + name + " refused, simulation unchanged: " + error.what());
  }
}

// Rebuilt with the new fabric (from frame 0): the springs' stiffness and damping come from the
// material when the model is built. Garments with a prebuilt model (saved edits) keep their
// springs and take only friction and drag from it.
void SimServer::SetMaterial(const costume_lcm::command& command) {
  const costume_lcm::material_parameters& p = command.material;
  const int count = static_cast<int>(scene_.garments.size());
  if (command.garment < -1 || command.garment >= count) {
    ++ignored_.commands_refused;
    Warn("command SET_MATERIAL: garment = " + std::to_string(command.garment) +
         ": must be -1 (every garment) or in [0, " + std::to_string(count - 1) + "]; ignored");
    return;
  }
  sim::SceneDescription scene = scene_;
  for (int g = 0; g < count; ++g) {
    if (command.garment >= 0 && g != command.garment) continue;
    sim::GarmentSpec& garment = scene.garments[g];
    sim::Material material = bus::FromMessage(p);
    material.name = garment.name + "_fabric";
    std::erase_if(scene.materials,
                  [&](const sim::Material& m) { return m.name == material.name; });
    scene.materials.push_back(material);
    garment.material = material.name;
  }
  try {
    Rebuild(scene);  // ValidateScene checks the material's ranges
  } catch (const sim::InputError& error) {
    ++ignored_.commands_refused;
    Warn(std::string("command SET_MATERIAL refused, fabric unchanged: ") + error.what());
  }
}

void SimServer::SaveVersion(const costume_lcm::command& command) {
  SceneCatalog* catalog = OpenCatalog("SAVE_VERSION");
  if (catalog == nullptr) {
    ++ignored_.commands_refused;
    return;
  }
  if (scene_.garments.empty()) {
    ++ignored_.commands_refused;
    Warn("command SAVE_VERSION: the scene has no garment; nothing saved");
    return;
  }
  for (const sim::GarmentSpec& garment : scene_.garments) {
    try {
      const SavedVersion saved = catalog->SaveVersion(*simulation_, garment.name, command.name);
      Warn("command SAVE_VERSION: saved " + saved.entry + " version " +
           std::to_string(saved.version) + " '" + command.name + "'");
    } catch (const std::exception& error) {
      ++ignored_.commands_refused;
      Warn("command SAVE_VERSION: garment '" + garment.name + "' not saved: " + error.what());
    }
  }
}

namespace {

std::string FormatAngles(const std::vector<double>& angles) {
  return sim::FormatValues({angles[0], angles[1], angles[2]});
}

/// The posture a SET_POSTURE command names for `skeleton`: the named joints rotated by their
/// angles (degrees about the joint's rest x, y, z axes, applied in that order, as
/// assets/scene_file.cc ParsePosture), every other joint at rest, the avatar turned by
/// heading_degrees about +y and left at `root_translation`. Throws InputError naming the
/// field for an unknown or unmapped joint name, angles or a heading not finite or beyond
/// ±sim::kMaxPostureDegrees.
sim::Pose PostureOf(const costume_lcm::command& command, const sim::Skeleton& skeleton,
                    const Eigen::Vector3d& root_translation) {
  sim::Pose pose;
  pose.rotations.assign(skeleton.num_joints(), Eigen::Quaterniond::Identity());
  pose.root_translation = root_translation;
  const std::string range = "within [-" + sim::FormatValue(sim::kMaxPostureDegrees) + ", " +
                            sim::FormatValue(sim::kMaxPostureDegrees) + "]";
  const auto within = [](double degrees) {
    return std::abs(degrees) <= sim::kMaxPostureDegrees;  // false for NaN too
  };
  if (!within(command.heading_degrees)) {
    throw sim::InputError("command SET_POSTURE: heading_degrees = " +
                          std::to_string(command.heading_degrees) + ": must be finite, " + range);
  }
  pose.orientation = sim::PostureRotation({0.0, command.heading_degrees, 0.0});
  for (int i = 0; i < command.num_joints; ++i) {
    const std::string field = "command SET_POSTURE: joint_names[" + std::to_string(i) + "] = '" +
                              command.joint_names[i] + "'";
    const std::optional<sim::HAnimJoint> joint = sim::ParseHAnimName(command.joint_names[i]);
    if (!joint) throw sim::InputError(field + ": not an H-Anim joint name (e.g. 'l_shoulder')");
    const int index = skeleton.Find(*joint);
    if (index < 0) throw sim::InputError(field + ": the avatar maps no joint onto it");
    const std::vector<double>& a = command.joint_angles[i];
    if (a.size() != 3) {
      throw sim::InputError("command SET_POSTURE: joint_angles[" + std::to_string(i) +
                            "] holds " + std::to_string(a.size()) + " values: must be 3");
    }
    if (!within(a[0]) || !within(a[1]) || !within(a[2])) {
      throw sim::InputError("command SET_POSTURE: joint_angles[" + std::to_string(i) + "] = " +
                            FormatAngles(a) + " degrees for '" + command.joint_names[i] +
                            "': each must be finite, " + range);
    }
    pose.rotations[index] = sim::PostureRotation({a[0], a[1], a[2]});
  }
  return pose;
}

/// The arms' spread a SET_POSTURE command asks for. Throws sim::InputError naming the field
/// for an unknown mode or an angle outside [0, kMaxArmSpreadDegrees].
sim::ArmSpreadRequest ArmSpreadRequestOf(const costume_lcm::command& command) {
  using C = costume_lcm::command;
  sim::ArmSpreadRequest request;
  switch (command.arm_spread_mode) {
    case C::ARM_SPREAD_KEEP: return request;
    case C::ARM_SPREAD_AUTO: request.kind = sim::ArmSpreadRequest::Kind::kAuto; return request;
    case C::ARM_SPREAD_GIVEN: break;
    default:
      throw sim::InputError("command SET_POSTURE: arm_spread_mode = " +
                            std::to_string(command.arm_spread_mode) +
                            ": must be 0 (keep), 1 (auto) or 2 (given)");
  }
  request.kind = sim::ArmSpreadRequest::Kind::kGiven;
  for (int side = 0; side < 2; ++side) {
    const double degrees = command.arm_spread_degrees[side];
    if (!(degrees >= 0.0 && degrees <= sim::kMaxArmSpreadDegrees)) {
      throw sim::InputError("command SET_POSTURE: arm_spread_degrees[" + std::to_string(side) +
                            "] = " + std::to_string(degrees) + ": must be within [0, " +
                            sim::FormatValue(sim::kMaxArmSpreadDegrees) + "]");
    }
    request.angle[side] = degrees * M_PI / 180.0;
  }
  return request;
}

}  // namespace

// The cloth keeps its state: only the body moves, gradually (posture_transition), and the
// cloth follows it through contacts and attachments. The server's scene takes the posture
// too, so a STOP rebuilds in it.
void SimServer::SetPosture(const costume_lcm::command& command) {
  const sim::AvatarMotion* avatar = simulation_->avatar();
  if (avatar == nullptr || !scene_.avatar) {
    ++ignored_.commands_refused;
    Warn("command SET_POSTURE: the scene has no avatar; ignored");
    return;
  }
  try {
    const sim::Pose posture = PostureOf(command, avatar->avatar().skeleton(),
                                        avatar->settings().posture.root_translation);
    const sim::ArmSpreadRequest spread = ArmSpreadRequestOf(command);
    simulation_->SetPosture(posture, options_.posture_transition, spread, &arm_spreads_);
    *scene_.avatar = sim::WithPosture(*scene_.avatar, posture, spread);
    const sim::ArmSpreadFit& chosen = simulation_->arm_spread();
    if (spread.kind == sim::ArmSpreadRequest::Kind::kAuto && chosen.measured &&
        (chosen.angle[0] > 0.0 || chosen.angle[1] > 0.0)) {
      Warn("posture set: " + sim::DescribeArmSpread(chosen));
    }
  } catch (const sim::InputError& error) {
    ++ignored_.commands_refused;
    Warn(std::string(error.what()) + "; posture unchanged");
  }
}

// ---- grabs -------------------------------------------------------------------------------

void SimServer::ReleaseGrab() {
  simulation_->ReleaseGrab();
  last_finished_grab_id_ = std::max(last_finished_grab_id_, grab_id_);
}

void SimServer::ApplyLatestGrab() {
  // A restarted haptic server numbers its grabs from 0 again.
  if (grab_counts_->sender_restarts != grab_sender_restarts_) {
    grab_sender_restarts_ = grab_counts_->sender_restarts;
    last_finished_grab_id_ = -1;
    if (grabbing()) ReleaseGrab();
  }
  if (!has_new_grab_) {
    if (grabbing() && ++frames_since_grab_message_ >
                         std::llround(options_.grab_timeout * scene_.frame_rate)) {
      ++ignored_.grabs_timed_out;
      Warn("grab " + std::to_string(grab_id_) + ": no grab message for " +
           std::to_string(options_.grab_timeout) + " s; released");
      ReleaseGrab();
    }
    return;
  }
  has_new_grab_ = false;
  frames_since_grab_message_ = 0;
  const costume_lcm::grab& message = latest_grab_;
  if (mode_ != Mode::kEditing) {
    ++ignored_.grabs_in_animation;
    return;
  }
  if (grabbing() && message.device_id != grab_device_) {
    ++ignored_.grabs_other_device;
    return;
  }
  if (grabbing() && message.grab_id < grab_id_) {
    ++ignored_.grabs_stale_id;  // a late message of an earlier press
    return;
  }
  const bool pressed = message.mode == costume_lcm::grab::MODE_GRAB &&
                       (message.buttons & kGrabButton) != 0;
  if (!pressed) {
    if (grabbing()) ReleaseGrab();
    return;
  }
  const bool same_grab = grabbing() && message.grab_id == grab_id_;
  if (!same_grab && message.grab_id <= last_finished_grab_id_) {
    ++ignored_.grabs_stale_id;  // that press was released; a new press has a new id
    return;
  }
  const sim::Grab grab = ToGrab(message);
  if (!sim::IsValidGrab(grab)) {
    ++ignored_.grabs_invalid;
    return;
  }
  if (grabbing() && !same_grab) ReleaseGrab();  // a new press: a new selection
  if (message.gaussian_sigma > 0.0 && !warned_sigma_) {
    warned_sigma_ = true;
    Warn("grab.gaussian_sigma = " + std::to_string(message.gaussian_sigma) +
         " m is not supported: the simulation uses sigma = radius/2 (grab.h)");
  }
  simulation_->SetGrab(grab);
  grab_id_ = message.grab_id;
  grab_device_ = message.device_id;
}

// ---- publishing --------------------------------------------------------------------------

void SimServer::PublishFrame() {
  using F = costume_lcm::cloth_frame;
  const sim::Points& x = simulation_->state().positions;
  const int n = static_cast<int>(x.rows());
  const int num_chunks = std::max(1, (n + F::MAX_PARTICLES_PER_CHUNK - 1) /
                                         F::MAX_PARTICLES_PER_CHUNK);
  F& m = frame_message_;
  m.frame = frame_;
  m.sim_time = simulation_->state().time;
  m.model_revision = model_revision_;
  m.mode = ToLcmMode(mode_);
  m.grab_seq = grab_seq_;
  m.command_seq = command_seq_;
  m.haptic_command_seq = haptic_command_seq_;
  m.total_particles = n;
  m.num_chunks = static_cast<std::int16_t>(num_chunks);
  for (int k = 0; k < num_chunks; ++k) {
    const int first = k * F::MAX_PARTICLES_PER_CHUNK;
    const int count = std::min<int>(F::MAX_PARTICLES_PER_CHUNK, n - first);
    m.utime = bus::NowUtime();
    m.chunk_index = static_cast<std::int16_t>(k);
    m.first_particle = first;
    m.num_particles = static_cast<std::int16_t>(count);
    m.x.resize(count);
    m.y.resize(count);
    m.z.resize(count);
    for (int i = 0; i < count; ++i) {
      m.x[i] = static_cast<float>(x(first + i, 0));
      m.y[i] = static_cast<float>(x(first + i, 1));
      m.z[i] = static_cast<float>(x(first + i, 2));
    }
    frame_publisher_.Publish(m);
  }
}

// The patch: the grabbed particles first (selected, with their Gaussian weight at the
// current sphere, as ApplyGrab uses it), then every other end of a spring touching one of
// them; the springs are every spring with a selected end, so both ends are in the patch.
void SimServer::PublishPatch() {
  using P = costume_lcm::haptic_patch;
  const sim::ClothModel& model = simulation_->model();
  const sim::ClothState& state = simulation_->state();
  patch_particles_.clear();
  patch_springs_.clear();
  for (int p : simulation_->grabbed()) {
    patch_slot_[p] = static_cast<int>(patch_particles_.size());
    patch_particles_.push_back(p);
  }
  const int num_selected = static_cast<int>(patch_particles_.size());
  for (int k = 0; k < model.num_springs(); ++k) {
    const sim::Spring& s = model.springs()[k];
    const bool a_in = patch_slot_[s.a] >= 0 && patch_slot_[s.a] < num_selected;
    const bool b_in = patch_slot_[s.b] >= 0 && patch_slot_[s.b] < num_selected;
    if (!a_in && !b_in) continue;
    patch_springs_.push_back(k);
    for (int end : {s.a, s.b}) {
      if (patch_slot_[end] >= 0) continue;
      patch_slot_[end] = static_cast<int>(patch_particles_.size());
      patch_particles_.push_back(end);
    }
  }
  const int np = static_cast<int>(patch_particles_.size());
  const int ns = static_cast<int>(patch_springs_.size());
  const int num_chunks =
      std::max({1, (np + P::MAX_PARTICLES_PER_CHUNK - 1) / P::MAX_PARTICLES_PER_CHUNK,
                (ns + P::MAX_SPRINGS_PER_CHUNK - 1) / P::MAX_SPRINGS_PER_CHUNK});
  P& m = patch_message_;
  m.frame = frame_;
  m.model_revision = model_revision_;
  m.device_id = grab_device_;
  m.grab_id = grab_id_;
  const sim::Grab& grab = simulation_->grab();
  for (int i = 0; i < 3; ++i) m.centre[i] = grab.centre[i];
  m.radius = grab.radius;
  m.gaussian_sigma = 0.5 * grab.radius;  // grab.h: s = (r/2)²
  m.num_chunks = static_cast<std::int16_t>(num_chunks);
  m.total_particles = np;
  m.total_springs = ns;
  for (int k = 0; k < num_chunks; ++k) {
    const int first_p = std::min(np, k * P::MAX_PARTICLES_PER_CHUNK);
    const int count_p = std::min<int>(P::MAX_PARTICLES_PER_CHUNK, np - first_p);
    const int first_s = std::min(ns, k * P::MAX_SPRINGS_PER_CHUNK);
    const int count_s = std::min<int>(P::MAX_SPRINGS_PER_CHUNK, ns - first_s);
    m.utime = bus::NowUtime();
    m.chunk_index = static_cast<std::int16_t>(k);
    m.first_particle = first_p;
    m.first_spring = first_s;
    m.num_particles = static_cast<std::int16_t>(count_p);
    for (auto* v : {&m.x, &m.y, &m.z, &m.vx, &m.vy, &m.vz, &m.mass, &m.weight}) {
      v->resize(count_p);
    }
    m.particle_index.resize(count_p);
    m.selected.resize(count_p);
    for (int i = 0; i < count_p; ++i) {
      const int slot = first_p + i;
      const int p = patch_particles_[slot];
      const Eigen::Vector3d x = state.positions.row(p).transpose();
      m.particle_index[i] = p;
      m.x[i] = static_cast<float>(x.x());
      m.y[i] = static_cast<float>(x.y());
      m.z[i] = static_cast<float>(x.z());
      m.vx[i] = static_cast<float>(state.velocities(p, 0));
      m.vy[i] = static_cast<float>(state.velocities(p, 1));
      m.vz[i] = static_cast<float>(state.velocities(p, 2));
      m.mass[i] = static_cast<float>(model.masses()[p]);
      m.selected[i] = slot < num_selected;
      m.weight[i] = slot < num_selected ? static_cast<float>(sim::GrabWeight(grab, x)) : 0.0f;
    }
    m.num_springs = static_cast<std::int16_t>(count_s);
    for (auto* v : {&m.spring_a, &m.spring_b}) v->resize(count_s);
    for (auto* v : {&m.stiffness, &m.damping, &m.rest_length}) v->resize(count_s);
    for (int i = 0; i < count_s; ++i) {
      const sim::Spring& s = model.springs()[patch_springs_[first_s + i]];
      m.spring_a[i] = patch_slot_[s.a];
      m.spring_b[i] = patch_slot_[s.b];
      m.stiffness[i] = static_cast<float>(s.stiffness);
      m.damping[i] = static_cast<float>(s.damping);
      m.rest_length[i] = static_cast<float>(s.rest_length);
    }
    patch_publisher_.Publish(m);
  }
  for (int p : patch_particles_) patch_slot_[p] = -1;
}

void SimServer::PublishStatusIfDue(double work_ms) {
  ++period_ticks_;
  period_work_ms_ += work_ms;
  period_max_work_ms_ = std::max(period_max_work_ms_, work_ms);
  const auto ticks_per_status =
      std::max<std::int64_t>(1, std::llround(options_.status_period * scene_.frame_rate));
  if (ticks_ % ticks_per_status == 0 || !warnings_.empty()) PublishStatus();
}

void SimServer::AddSolverHealthWarnings() {
  const sim::SolverSettings& solver = simulation_->scene().solver;
  const auto number = [](double value) {
    std::ostringstream text;
    text << value;  // 0.01, 1e-06: as the user typed it, not std::to_string's 0.010000
    return text.str();
  };
  if (period_unconverged_frames_ > 0) {
    warnings_.push_back(
        "solver: " + std::to_string(period_unconverged_frames_) + " of " +
        std::to_string(period_ticks_) + " frames stopped at the iteration cap (max_iterations = " +
        std::to_string(solver.max_iterations) + ") before the tolerance (" +
        number(solver.tolerance) + "): the cloth lags its physics; raise the cap, add "
        "substeps or use the multigrid solver");
  }
  if (period_rolled_back_steps_ > 0) {
    warnings_.push_back(
        "solver: " + std::to_string(period_rolled_back_steps_) + " steps produced non-finite "
        "values and were undone (the cloth held still for them): tighten the tolerance (now " +
        number(solver.tolerance) + "), add substeps (now " +
        std::to_string(solver.substeps) + ") or switch the strain limit on");
  }
  period_unconverged_frames_ = period_rolled_back_steps_ = 0;
}

void SimServer::PublishStatus() {
  using S = costume_lcm::status;
  AddSolverHealthWarnings();
  const auto now = std::chrono::steady_clock::now();
  const double elapsed = std::chrono::duration<double>(now - period_start_).count();
  S m{};
  m.utime = bus::NowUtime();
  m.process = options_.process_name;
  m.pid = static_cast<std::int32_t>(getpid());
  m.target_rate = scene_.frame_rate;
  m.measured_rate = elapsed > 0.0 ? static_cast<double>(period_ticks_) / elapsed : 0.0;
  m.frame_time_ms = period_ticks_ > 0 ? period_work_ms_ / static_cast<double>(period_ticks_) : 0;
  m.max_frame_time_ms = period_max_work_ms_;
  m.ticks = ticks_;
  m.overruns = overruns_;
  m.missed_ticks = overruns_;
  const PeriodFigures periods = ComputePeriodFigures(frame_periods_);
  frame_periods_.clear();
  m.period_p50_us = periods.p50_us;
  m.period_p99_us = periods.p99_us;
  m.period_p999_us = periods.p999_us;
  m.period_max_us = periods.max_us;
  m.solver_iterations = last_iterations_;
  m.mode = ToLcmMode(mode_);
  m.playback = ToLcmPlayback(playback_);
  m.frame = frame_;
  m.sim_time = simulation_->state().time;
  m.model_revision = model_revision_;
  m.undo_depth = simulation_->num_undoable_edits();
  m.redo_depth = redo_depth();
  const bus::ReceiveCounts commands = command_counts();
  const bus::ReceiveCounts& grabs = *grab_counts_;
  m.dropped_malformed = commands.malformed + grabs.malformed;
  m.dropped_oversized = commands.oversized + grabs.oversized;
  m.dropped_stale = commands.stale + grabs.stale;
  m.dropped_out_of_order = commands.out_of_order + grabs.out_of_order;
  m.warnings = warnings_;
  if (!standing_warning_.empty()) m.warnings.insert(m.warnings.begin(), standing_warning_);
  m.num_warnings = static_cast<std::int16_t>(m.warnings.size());
  status_publisher_.Publish(m);
  warnings_.clear();
  period_ticks_ = 0;
  period_work_ms_ = period_max_work_ms_ = 0.0;
  period_start_ = now;
}

}  // namespace costume::sim_app
