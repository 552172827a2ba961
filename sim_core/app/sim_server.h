#pragma once
/// @file
/// The 60 Hz simulation server (issue 5; docs/processes.md): owns one sim::Simulation, takes
/// grabs and commands from the bus, and publishes cloth frames, haptic patches and status.
/// The conversions between costume_lcm messages and sim types live here, not in sim_core,
/// which knows nothing of LCM (STYLE.md §1).
///
/// Threading: one thread. Step() and Run() drain the bus themselves (HandleSubscriptions(0)),
/// so handlers run on the loop's thread and nothing is shared.

#include <Eigen/Core>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "bus/message_bus.h"
#include "bus/receive_filter.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"
#include "lcm_types/costume_lcm/status.hpp"
#include "sim_core/scene/scene_description.h"
#include "sim_core/scene/simulation.h"

namespace costume::sim_app {

/// Mode A (animation) or mode B (editing), exclusive as in the paper (§5).
enum class Mode { kAnimation, kEditing };

/// Whether frames advance. STOP also rebuilds the simulation (back to frame 0).
enum class Playback { kStopped, kPlaying, kPaused };

/// The next wake-up of a fixed-rate loop on an absolute clock.
struct Deadline {
  /// The next deadline, at or after `now` [ns].
  std::int64_t next = 0;
  /// Deadlines passed over because the frame ran past them (0 when on time) [-].
  std::int64_t missed = 0;
};

/// Given the deadline the frame that just finished was scheduled for (`deadline` [ns]), the
/// clock after its work (`now` [ns], same origin) and the period (> 0) [ns]: the next
/// deadline is deadline + period when that is not yet past (>= now); otherwise the first
/// deadline + k·period after now, the k − 1 deadlines passed over counted as missed. Lag never
/// accumulates: deadlines stay on the original grid. Never throws; never allocates.
Deadline NextDeadline(std::int64_t deadline, std::int64_t now, std::int64_t period);

/// What a LOAD_* command loads.
enum class LoadKind { kAvatar, kCostume, kAnimation };

/// A garment saved by SAVE_VERSION.
struct SavedVersion {
  /// The catalogue entry as messages name it ("garment 'skirt' (id 7)").
  std::string entry;
  /// The version number the save made, >= 2 for a seeded entry.
  int version = 0;
};

/// The catalogue as the server uses it, behind an interface so that the server library links
/// no database (sim_core/app/catalog_link.h implements it over catalog::Catalog; tests may
/// script it).
class SceneCatalog {
 public:
  virtual ~SceneCatalog() = default;
  /// Changes `scene` as LOAD_AVATAR, LOAD_COSTUME or LOAD_ANIMATION asks for the entry `id`
  /// (> 0) or, when id <= 0, the entry of that kind called `name`; returns the entry as
  /// messages name it. Throws sim::InputError naming the entry (unknown id or name, wrong
  /// kind, data its importer refuses) and then leaves `scene` unchanged.
  virtual std::string Load(LoadKind kind, std::int64_t id, const std::string& name,
                           sim::SceneDescription& scene) = 0;
  /// Stores garment `garment` of `simulation` (its current rest lengths included) as a new
  /// version of the catalogue's garment entry of the same name, labelled `label`. Throws
  /// sim::InputError naming the garment when it has no entry or the save fails.
  virtual SavedVersion SaveVersion(const sim::Simulation& simulation, const std::string& garment,
                                   const std::string& label) = 0;
};

struct SimServerOptions {
  /// Mode at start.
  Mode mode = Mode::kAnimation;
  /// Playing (true) or stopped at frame 0 (false) at start.
  bool start_playing = true;
  /// Time between status messages [s] > 0.
  double status_period = 1.0;
  /// A grab whose messages stop for this long is released (the haptic server died) [s] > 0.
  double grab_timeout = 0.25;
  /// SET_POSTURE moves the avatar to the new posture over this much simulated time [s] >= 0,
  /// so the cloth follows the body instead of being thrown off by a jump.
  double posture_transition = 0.5;
  /// Acceptance of grab and command messages (size, age, order).
  bus::ReceivePolicy receive_policy = {};
  /// Opens the catalogue at the first command that needs it (LOAD_*, SAVE_VERSION); called
  /// again at the next such command after a failure (an InputError it throws becomes a
  /// status warning). Empty: those commands are refused with a warning.
  std::function<std::unique_ptr<SceneCatalog>()> open_catalog = nullptr;
  /// The catalogue's URL as warnings name it (password starred out).
  std::string catalog_url;
  /// Process name in status.
  std::string process_name = "sim_server";
  /// The clock Run paces frames on [ns] and its absolute sleep; empty: CLOCK_MONOTONIC and
  /// clock_nanosleep(TIMER_ABSTIME). Tests script wake-ups with them.
  std::function<std::int64_t()> clock_now = nullptr;
  std::function<void(std::int64_t)> clock_sleep_until = nullptr;
};

/// Frame-period figures of one status period, as status.period_*_us carries them.
struct PeriodFigures {
  double p50_us = 0.0;   ///< median period [µs]
  double p99_us = 0.0;   ///< 99th percentile [µs]
  double p999_us = 0.0;  ///< 99.9th percentile [µs]
  double max_us = 0.0;   ///< longest [µs]
};

/// Nearest-rank percentiles of `periods` [ns] (any order; sorted in place). Zeros when empty.
/// Allocates nothing; never throws.
PeriodFigures ComputePeriodFigures(std::vector<std::int64_t>& periods);

/// Grab and command messages the server received but did not act on, since start.
struct IgnoredCounts {
  std::int64_t grabs_in_animation = 0;  ///< grabs in mode A
  std::int64_t grabs_invalid = 0;       ///< non-finite centre/force or radius <= 0
  std::int64_t grabs_stale_id = 0;      ///< a grab_id older than the current or a released one
  std::int64_t grabs_other_device = 0;  ///< another device's grab while one is held
  std::int64_t grabs_timed_out = 0;     ///< grabs released because their messages stopped
  std::int64_t commands_refused = 0;    ///< unknown kind, bad field, or not yet available
};

/// The simulation server. Not copyable; holds references to the bus.
class SimServer {
 public:
  /// Builds the simulation for `scene` and subscribes to COSTUME_GRAB, COSTUME_COMMAND and
  /// COSTUME_COMMAND_HAPTIC on `bus` (which must outlive the server). Throws
  /// sim::InputError for a scene the simulation refuses or bad options.
  SimServer(bus::MessageBus& bus, sim::SceneDescription scene, SimServerOptions options = {});
  SimServer(const SimServer&) = delete;
  SimServer& operator=(const SimServer&) = delete;

  /// One frame's work without the clock: drain the bus (HandleSubscriptions(0)), apply the
  /// commands in arrival order and then the latest grab, advance the simulation one frame
  /// when playing, publish the cloth frame, the patch while grabbing, and status when due or
  /// when a warning was raised. Never throws for bad messages (they are counted); a
  /// rebuild the scene refuses keeps the old simulation and raises a warning.
  void Step();

  /// Steps at the scene's frame rate on CLOCK_MONOTONIC with absolute sleeps (NextDeadline)
  /// until `stop` is set or `max_frames` (> 0) Steps have run. Returns the Steps run.
  std::int64_t Run(const std::atomic<bool>& stop, std::int64_t max_frames = 0);

  /// Publishes a status message now and clears the pending warnings.
  void PublishStatus();
  /// Warnings about the period's solves (iteration cap reached, steps undone), if any.
  void AddSolverHealthWarnings();
  /// Adds a warning to the next status (which is then published at the end of this Step).
  void Warn(std::string warning);
  /// A warning repeated in every status from now on (e.g. a real-time priority refused to a
  /// thread of the process), so a GUI that starts later still sees it. Empty: none.
  void SetStandingWarning(std::string warning) { standing_warning_ = std::move(warning); }

  const sim::Simulation& simulation() const { return *simulation_; }
  /// The scene a STOP rebuilds (with the postures and solver set since start).
  const sim::SceneDescription& scene() const { return scene_; }
  Mode mode() const { return mode_; }
  Playback playback() const { return playback_; }
  /// Frames advanced since the scene was (re)built: cloth_frame.frame.
  std::int64_t frame() const { return frame_; }
  /// +1 at each rest-length change (stretch elimination, undo, redo) and rebuild.
  std::int64_t model_revision() const { return model_revision_; }
  std::int64_t ticks() const { return ticks_; }
  /// Frame deadlines Run passed over because a frame (or a wake-up) came too late, since
  /// start: status.overruns and status.missed_ticks.
  std::int64_t overruns() const { return overruns_; }
  /// Redo stack depth (sphere edits undone that REDO can re-apply).
  int redo_depth() const { return static_cast<int>(redo_.size()); }
  const IgnoredCounts& ignored() const { return ignored_; }
  /// Drop counters of the grab subscription and of both command subscriptions (summed).
  bus::ReceiveCounts grab_counts() const { return *grab_counts_; }
  bus::ReceiveCounts command_counts() const;
  /// The grab being applied: its message id, or -1.
  std::int64_t active_grab_id() const { return grabbing() ? grab_id_ : -1; }
  /// Warnings waiting for the next status.
  const std::vector<std::string>& pending_warnings() const { return warnings_; }

 private:
  /// One sphere edit, for REDO: the sphere it eliminated stretch in.
  struct SphereEdit {
    Eigen::Vector3d centre;
    double radius = 0.0;
  };

  void Rebuild(const sim::SceneDescription& scene);
  void ApplyCommand(const costume_lcm::command& command);
  void SetMode(Mode mode);
  void EliminateStretch(const costume_lcm::command& command);
  void Undo();
  void Redo();
  void SetSolver(const costume_lcm::solver_parameters& solver);
  void SetCollision(const costume_lcm::collision_parameters& collision);
  void SetPosture(const costume_lcm::command& command);
  SceneCatalog* OpenCatalog(const std::string& command_name);
  void Load(LoadKind kind, const costume_lcm::command& command);
  void SetMaterial(const costume_lcm::command& command);
  void SaveVersion(const costume_lcm::command& command);
  void ApplyLatestGrab();
  void ReleaseGrab();
  void PublishFrame();
  void PublishPatch();
  void PublishStatusIfDue(double work_ms);

  bus::MessageBus& bus_;
  sim::SceneDescription scene_;
  SimServerOptions options_;
  std::unique_ptr<SceneCatalog> catalog_;  ///< opened lazily (OpenCatalog)
  /// Kept across rebuilds (STOP, a fabric, a costume on the same body): the arms' spread
  /// chosen for the scene's clip, and the avatar's superquadric collider with its drawings.
  sim::ArmSpreadMemo arm_spreads_;
  sim::ColliderMemo colliders_;
  std::unique_ptr<sim::Simulation> simulation_;

  bus::Publisher<costume_lcm::cloth_frame> frame_publisher_;
  bus::Publisher<costume_lcm::haptic_patch> patch_publisher_;
  bus::Publisher<costume_lcm::status> status_publisher_;
  std::shared_ptr<const bus::ReceiveCounts> grab_counts_;
  std::shared_ptr<const bus::ReceiveCounts> command_counts_;
  std::shared_ptr<const bus::ReceiveCounts> haptic_command_counts_;

  // Received this Step, applied at its end of the drain.
  std::vector<costume_lcm::command> commands_;
  costume_lcm::grab latest_grab_{};
  /// seq of the last grab, command and haptic command taken in (−1: none yet).
  std::int64_t grab_seq_ = -1;
  std::int64_t command_seq_ = -1;
  std::int64_t haptic_command_seq_ = -1;
  bool has_new_grab_ = false;
  std::int64_t frames_since_grab_message_ = 0;
  std::int64_t grab_sender_restarts_ = 0;

  Mode mode_ = Mode::kAnimation;
  Playback playback_ = Playback::kPlaying;
  std::int64_t frame_ = 0;
  std::int64_t model_revision_ = 0;
  int last_iterations_ = -1;

  // The grab being applied (the grab itself, and whether one is held, are the
  // simulation's: Simulation::grab(), grabbing()).
  bool grabbing() const { return simulation_ && simulation_->grabbing(); }
  std::int64_t grab_id_ = -1;
  /// Grab ids at or below this are over (released or superseded): never restarted.
  std::int64_t last_finished_grab_id_ = -1;
  std::int8_t grab_device_ = 0;
  bool warned_sigma_ = false;

  std::vector<SphereEdit> edits_;  ///< applied sphere edits, parallel to the undo stack
  std::vector<SphereEdit> redo_;

  // Messages and scratch, kept so publishing allocates only when something grows.
  costume_lcm::cloth_frame frame_message_{};
  costume_lcm::haptic_patch patch_message_{};
  std::vector<int> patch_particles_;
  std::vector<int> patch_springs_;
  std::vector<int> patch_slot_;  ///< garment particle -> patch index, or -1

  IgnoredCounts ignored_;
  // Status accounting.
  std::vector<std::string> warnings_;
  std::string standing_warning_;
  std::int64_t ticks_ = 0;
  std::int64_t overruns_ = 0;
  std::int64_t period_ticks_ = 0;
  /// Frames of this status period whose solve stopped at the iteration cap, and steps undone
  /// for non-finite values: reported once per status, with the settings to change.
  int period_unconverged_frames_ = 0;
  int period_rolled_back_steps_ = 0;
  double period_work_ms_ = 0.0;
  double period_max_work_ms_ = 0.0;
  /// Wake-to-wake frame periods Run measured in this status period [ns] (capacity reserved
  /// once; periods beyond it are not recorded).
  std::vector<std::int64_t> frame_periods_;
  std::chrono::steady_clock::time_point period_start_;
};

}  // namespace costume::sim_app
