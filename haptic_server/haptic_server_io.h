#pragma once
/// @file
/// The haptic server's I/O side (issue 5): the only part of the process that speaks LCM.
///
///   - PatchAssembler: haptic_patch chunks (COSTUME_HAPTIC_PATCH) → one HapticPatch for the
///     tick's TripleBuffer. Incomplete, mixed-frame and inconsistent assemblies are dropped
///     and counted, never handed over.
///   - GrabTracker: the grab protocol from the tick's outgoing states (every tick's state
///     passes through it, so no press is missed): grab button pressed → a new grab_id and
///     MODE_GRAB, centre = the tip (scene frame); released → MODE_HOVER.
///   - Converters: OutgoingDeviceState → device_state, feedback and grab messages.
///   - HapticServerIo: one round of the I/O thread is Poll(): dispatch received messages, hand
///     complete patches to the tick (TripleBuffer::Publish, no lock), drain the tick's SPSC
///     queue and publish (nothing is ever published from the tick), status once per second.
///     Start()/Stop() run Poll on a thread of its own; tests call Poll directly, interleaved
///     with HapticLoop::Run on a FakeClock.
///
/// F_h, the hand's force on the cloth (grab.force), is the reaction to the feedback:
/// F_h = −FeedbackForce at the tip, scene frame, before ForceSafety (grab_forces.h). The local
/// model moves the selected particles with the tip, so F(u) grows as the hand pulls away from
/// where the cloth was at the last frame: the coupling between hand and cloth is the cloth's own
/// boundary springs. Taken before the safety layer on purpose: clamping and ramping protect the
/// device, they must not change the physics of the edit.

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "bus/command_resender.h"
#include "bus/message_bus.h"
#include "bus/receive_filter.h"
#include "bus/typed_bus.h"
#include "haptic_server/device.h"
#include "haptic_server/haptic_loop.h"
#include "haptic_server/haptic_tick.h"
#include "haptic_server/kernel_preemption.h"
#include "haptic_server/mouse_device.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/device_state.hpp"
#include "lcm_types/costume_lcm/feedback.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"
#include "lcm_types/costume_lcm/pointer_sample.hpp"
#include "lcm_types/costume_lcm/status.hpp"

namespace costume::haptics {

// ---- patch assembly ---------------------------------------------------------------------

/// What happened to haptic_patch chunks and assembled patches since construction.
struct PatchAssemblyCounts {
  /// Complete patches (all chunks of one frame, consistent) handed on.
  std::int64_t num_assembled = 0;
  /// Assemblies abandoned because a chunk of another frame arrived before they were complete
  /// (a lost chunk, or chunks of different frames mixed). Remedy: a lossy link; fewer chunks.
  std::int64_t num_incomplete = 0;
  /// Assemblies abandoned because a chunk of the same frame disagreed with the first one
  /// (num_chunks, totals, grab, revision, sphere) or the chunks did not add up to the totals.
  std::int64_t num_inconsistent = 0;
  /// Chunks refused on their own: chunk_index outside [0, num_chunks), negative or oversized
  /// totals, a range past the totals, a non-finite or non-positive sphere.
  std::int64_t num_invalid_chunks = 0;
  /// Chunks whose index had already arrived for the frame being assembled (ignored).
  std::int64_t num_duplicate_chunks = 0;
  /// Complete patches whose contents are unusable (PreparePatch: non-finite value, spring end
  /// out of range): not handed on. Remedy: see the simulation server's status.
  std::int64_t num_invalid_patches = 0;
  /// Complete patches for another device or a grab other than the current one (late patches
  /// of a released grab): not handed on.
  std::int64_t num_other_grab = 0;
};

/// Capacity of the assembler and of the tick's patch slots; beyond it chunks are invalid.
struct PatchCapacity {
  /// Particles of one assembled patch (> 0).
  int max_particles = 20'000;
  /// Springs of one assembled patch (> 0).
  int max_springs = 150'000;
  /// Chunks of one patch (> 0).
  int max_chunks = 256;
};

/// Collects the chunks of one simulation frame's patch. One frame is assembled at a time;
/// chunks of the typed bus's subscription arrive in seq order (the receive filter drops
/// out-of-order ones), so a chunk of another frame means the current one will not complete.
/// I/O thread only. Allocates only in the constructor.
class PatchAssembler {
 public:
  /// Throws costume::sim::InputError for a capacity field <= 0.
  explicit PatchAssembler(const PatchCapacity& capacity = {});

  /// Adds one chunk. Returns true when it completed a consistent patch: then patch() holds
  /// it (centre, radius, positions, velocities, springs; sequence = frame + 1 so that 0 keeps
  /// meaning "no patch"; derived fields not prepared) and grab_id()/device_id() name its grab.
  bool Add(const costume_lcm::haptic_patch& chunk);

  /// The last completed patch (valid until the next Add).
  const HapticPatch& patch() const { return patch_; }
  /// Its `selected` flags (1: the simulation applies F_h to the particle), one per particle.
  const std::vector<std::uint8_t>& selected() const { return selected_; }
  std::int64_t frame() const { return frame_; }
  std::int64_t grab_id() const { return grab_id_; }
  int device_id() const { return device_id_; }
  const PatchAssemblyCounts& counts() const { return counts_; }
  /// Counted by the caller, which decides what to hand on (HapticServerIo).
  PatchAssemblyCounts& mutable_counts() { return counts_; }

 private:
  bool ChunkIsValid(const costume_lcm::haptic_patch& chunk) const;
  bool MatchesHeader(const costume_lcm::haptic_patch& chunk) const;
  void Start(const costume_lcm::haptic_patch& chunk);
  void Abandon();
  void CopyChunk(const costume_lcm::haptic_patch& chunk);

  PatchCapacity capacity_;
  HapticPatch patch_;
  std::vector<std::uint8_t> selected_;
  std::vector<std::uint8_t> received_;  // per chunk index of the frame being assembled
  bool assembling_ = false;
  costume_lcm::haptic_patch header_;    // the first chunk's header fields (arrays left empty)
  int num_received_ = 0;
  std::int64_t particles_received_ = 0;
  std::int64_t springs_received_ = 0;
  std::int64_t frame_ = -1;
  std::int64_t grab_id_ = -1;
  int device_id_ = 0;
  PatchAssemblyCounts counts_;
};

/// Makes a prepared patch (PreparePatch) select what the simulation selected: the particles
/// flagged in `selected` (one flag per particle) get g(x_i) about patch.centre, all others 0,
/// and the boundary springs and num_selected are recomputed. The simulation keeps the particles
/// it selected when the grab started (a particle may have drifted out of the sphere, another
/// into it); PreparePatch's distance test alone would then disagree with the force it applies.
/// When no particle is flagged (a sender that does not fill the flags) the distance selection
/// stays. Does nothing to an invalid patch or on a size mismatch. Never throws; allocates only
/// beyond the patch's reserved capacity.
void ApplySelection(HapticPatch& patch, const std::vector<std::uint8_t>& selected);

// ---- the grab protocol ------------------------------------------------------------------

/// The state of the grab after one tick.
struct GrabState {
  /// costume_lcm::grab::MODE_GRAB while the grab button is held, MODE_HOVER otherwise.
  std::int8_t mode = costume_lcm::grab::MODE_HOVER;
  /// The current (or, hovering, the last) grab's id; -1 before the first press.
  std::int64_t grab_id = -1;
  /// This tick pressed or released the grab button.
  bool changed = false;
  /// This tick pressed the stretch-relief button (rising edge).
  bool stretch_relief_pressed = false;
};

/// Turns the button bits of successive ticks into grabs: each rising edge of kButtonGrab
/// starts a new grab_id (0, 1, 2, ... from construction). Never throws; never allocates.
class GrabTracker {
 public:
  const GrabState& Update(std::uint32_t buttons);
  const GrabState& state() const { return state_; }

 private:
  GrabState state_;
  std::uint32_t last_buttons_ = 0;
};

// ---- conversions ------------------------------------------------------------------------

/// costume_lcm::device_state::MODEL_* for a device model.
std::int8_t DeviceStateModel(DeviceModel model);

/// The feedback envelope (costume_lcm::feedback::ENVELOPE_*) and fade reason (FADE_*) that
/// ForceSafety's flags and gain describe.
void FeedbackEnvelope(const OutgoingDeviceState& state, std::int8_t& envelope,
                      std::int8_t& fade_reason);

/// Fills `message` (all but seq) from one tick's state. `utime` [µs since the epoch] is the
/// tick's time; position, orientation and velocity are already scene frame in `state`.
void ToDeviceStateMessage(const OutgoingDeviceState& state, std::int64_t utime, int device_id,
                          DeviceModel model, const DeviceLimits& limits,
                          costume_lcm::device_state& message);

/// Fills `message` (all but seq): force = the device force rotated into the scene frame
/// (workspace.rotation · F_device) [N]; requested_force = the unfiltered feedback [N];
/// patch_frame = patch_sequence − 1 (−1 before the first patch).
void ToFeedbackMessage(const OutgoingDeviceState& state, std::int64_t utime, int device_id,
                       const WorkspaceTransform& workspace, costume_lcm::feedback& message);

/// Fills `message` (all but seq): centre = tip (scene), radius [m], gaussian_sigma = r/2 (the
/// standard deviation of grab_forces.h), force = F_h = −feedback (scene) while grabbing and
/// zero while hovering, coupling_stiffness [N/m] (0: the simulation applies F_h instead).
void ToGrabMessage(const OutgoingDeviceState& state, const GrabState& grab, std::int64_t utime,
                   int device_id, double radius, double coupling_stiffness,
                   costume_lcm::grab& message);

// ---- the I/O thread ---------------------------------------------------------------------

/// Measures the work time of each tick of a wrapped handler (for status.frame_time_ms): two
/// clock reads per tick and relaxed atomics. Never allocates; never throws.
class TimedTickHandler final : public TickHandler {
 public:
  /// `inner` and `clock` must outlive this.
  TimedTickHandler(TickHandler& inner, LoopClock& clock) : inner_(inner), clock_(clock) {}
  void Tick(const TickInfo& info) override;
  /// Sum and maximum of the work times [ns] and the number of ticks since the last call;
  /// resets them (I/O thread).
  void TakeWorkTimes(std::int64_t& sum_ns, std::int64_t& max_ns, std::int64_t& count);

 private:
  TickHandler& inner_;
  LoopClock& clock_;
  std::atomic<std::int64_t> sum_ns_{0};
  std::atomic<std::int64_t> max_ns_{0};
  std::atomic<std::int64_t> count_{0};
};

/// A device wrapper whose ReleaseGrab() makes the grab button read as released, so that
/// ForceSafety fades the force to zero (fade_time, 25 ms) before the process closes the
/// device: a clean shutdown never drops a force abruptly. Forwards everything else.
class ReleasableDevice final : public HapticDevice {
 public:
  /// `inner` must outlive this.
  explicit ReleasableDevice(HapticDevice& inner) : inner_(inner) {}
  std::string name() const override { return inner_.name(); }
  DeviceModel model() const override { return inner_.model(); }
  DeviceLimits limits() const override { return inner_.limits(); }
  DeviceStatus Open() override { return inner_.Open(); }
  DeviceStatus Close() override { return inner_.Close(); }
  DeviceFault Read(DeviceState& state) override;
  DeviceFault Write(const Eigen::Vector3d& force) override { return inner_.Write(force); }
  /// Any thread: from now on every button reads as released.
  void ReleaseGrab() { released_.store(true, std::memory_order_relaxed); }

 private:
  HapticDevice& inner_;
  std::atomic<bool> released_{false};
};

/// The grab sphere radii the server accepts [m], from --radius or the GUI's
/// KIND_SET_SELECTION_RADIUS command: 1 mm (below a particle spacing) to 10 m (a sphere over a
/// whole scene, as the stretch test's 1.5 m). The GUI's control offers 0.005–0.5 m.
inline constexpr double kMinRadius = 0.001;
inline constexpr double kMaxRadius = 10.0;

/// Options of HapticServerIo.
struct HapticServerIoOptions {
  /// Grab sphere radius r [m] in [kMinRadius, kMaxRadius] at start; the GUI changes it on a
  /// running server (KIND_SET_SELECTION_RADIUS on COSTUME_COMMAND).
  double radius = 0.05;
  /// Stiffness of the simulation's implicit coupling between the sphere and the grabbed
  /// cloth (grab.coupling_stiffness) [N/m] >= 0; 0 sends F_h as a force instead, which the
  /// 60 Hz explicit application makes unstable on light cloth (sim_core/scene/grab.h).
  double coupling_stiffness = 200.0;
  /// This device's index (device_state.device_id, grab.device_id), 0..127.
  int device_id = 0;
  /// Publish device_state, feedback and grab for every n-th tick (>= 1). The default 4 gives
  /// 250 Hz: the simulation takes the latest grab each 60 Hz frame, so 4 grabs per frame keep
  /// its F_h at most 4 ms old at a quarter of the traffic. A grab press or release is published
  /// on the tick it happens, whatever n.
  int publish_every = 4;
  /// Status period [s] > 0, on the loop clock.
  double status_period = 1.0;
  /// SCHED_FIFO priority the I/O thread asks for at Start (1..99; <= 0: stay at normal
  /// priority). It carries the round trip (patches in, grabs out), so it runs above ordinary
  /// work but below the 1 kHz tick (HapticLoopOptions::realtime_priority, 80 by default). A
  /// refusal is repeated in every status's warnings, as the tick's is.
  int io_priority = 70;
  /// Size limits of an assembled patch.
  PatchCapacity capacity;
  /// Checks on received haptic_patch chunks (age, order, size).
  bus::ReceivePolicy patch_policy;
  /// Checks on received pointer samples (SetPointerDevice).
  bus::ReceivePolicy pointer_policy;
  /// Checks on the GUI's commands (COSTUME_COMMAND; only SET_SELECTION_RADIUS is read here).
  bus::ReceivePolicy command_policy;
  /// Resending of the device buttons' commands until a cloth_frame acknowledges them.
  bus::ResendPolicy resend;
  /// Throws costume::sim::InputError naming the field, value and allowed range.
  void Validate() const;
};

/// Everything HapticServerIo has counted (I/O thread).
struct HapticServerIoCounts {
  PatchAssemblyCounts patches;
  /// Patches handed to the tick's TripleBuffer.
  std::int64_t num_patches_handed = 0;
  /// Outgoing tick states drained from the SPSC queue.
  std::int64_t num_states_drained = 0;
  std::int64_t num_device_states_published = 0;
  std::int64_t num_feedback_published = 0;
  std::int64_t num_grabs_published = 0;
  std::int64_t num_commands_published = 0;
  /// Further copies of unacknowledged commands (bus::CommandResender).
  std::int64_t num_commands_resent = 0;
  /// Commands given up unacknowledged after ResendPolicy::max_resends copies (a warning).
  std::int64_t num_commands_given_up = 0;
  /// SET_SELECTION_RADIUS commands taken (applied or pending until the grab ends).
  std::int64_t num_radius_commands = 0;
  /// SET_SELECTION_RADIUS commands refused for a radius out of range (a warning).
  std::int64_t num_radius_refused = 0;
  std::int64_t num_status_published = 0;
  /// Publishes the bus or the typed checks refused.
  std::int64_t num_publish_refused = 0;
  /// Pointer samples pushed into the mouse device.
  std::int64_t num_pointer_samples = 0;
  /// Pointer samples refused for a non-finite position (inside the view).
  std::int64_t num_pointer_invalid = 0;
};

/// The I/O side of the haptic server. All methods from one thread (the I/O thread, or a
/// test's), except Start/Stop.
class HapticServerIo {
 public:
  /// `bus`, `clock` (the loop's), `patches` and `outgoing` (the tick's) and `device` must
  /// outlive this. Subscribes to COSTUME_HAPTIC_PATCH, to COSTUME_COMMAND (the GUI's
  /// SET_SELECTION_RADIUS) and to COSTUME_CLOTH_FRAME (decoded only while a device-button
  /// command waits for its acknowledgement, haptic_command_seq), and reserves every patch slot of
  /// `patches` to options.capacity (call before the tick runs). Throws InputError for bad
  /// options or workspace.
  HapticServerIo(bus::MessageBus& bus, LoopClock& clock, PatchMailbox& patches,
                 OutgoingQueue& outgoing, const HapticDevice& device,
                 const WorkspaceTransform& workspace, const HapticServerIoOptions& options);
  ~HapticServerIo();
  HapticServerIo(const HapticServerIo&) = delete;
  HapticServerIo& operator=(const HapticServerIo&) = delete;

  /// Where status gets the loop's counters, period statistics, real-time status and work
  /// times, and the tick's counters. Any may be null (fields then zero). Before Start.
  void SetStatusSources(const HapticLoop* loop, const HapticTick* tick,
                        TimedTickHandler* timing);

  /// Feeds `mouse` (which must outlive this) from COSTUME_POINTER: each pointer_sample that
  /// passes the receive filter (options.pointer_policy) is mapped from the scene frame into
  /// the device frame (the workspace's inverse) and pushed; inside_view = false makes the
  /// device read "no data" with the buttons released (the force fades). Samples with a
  /// non-finite position inside the view are counted (num_pointer_invalid) and dropped.
  /// Call once, before Start. Throws InputError when called twice.
  void SetPointerDevice(MouseDevice* mouse);

  /// One round: dispatches received messages (waiting up to `timeout_ms` [ms] for the first),
  /// drains the tick's queue and publishes, and publishes status when due. Never throws for
  /// bad input (it is counted); a transport failure is counted as a warning.
  void Poll(int timeout_ms);
  /// Assembles and publishes status now (also called by Poll once per status_period).
  void PublishStatus();

  /// Runs Poll(2) on a new thread until Stop. Stop drains the queue one last time and joins.
  void Start();
  void Stop();

  /// The counters (I/O thread; the patch counts are the assembler's).
  const HapticServerIoCounts& counts() {
    counts_.patches = assembler_.counts();
    return counts_;
  }
  /// Messages the patch subscription dropped (malformed, oversized, stale, out of order).
  const bus::ReceiveCounts& patch_receive_counts() const { return *patch_receive_; }
  /// The same for the pointer subscription (all zero without SetPointerDevice).
  bus::ReceiveCounts pointer_receive_counts() const {
    return pointer_receive_ ? *pointer_receive_ : bus::ReceiveCounts{};
  }
  const GrabState& grab_state() const { return grabs_.state(); }
  /// The radius [m] of the grab in progress, or of the next grab while hovering.
  double radius() const { return radius_; }
  /// The GUI's command subscription's counts.
  const bus::ReceiveCounts& command_receive_counts() const { return *command_receive_; }

 private:
  void OnPatchChunk(const costume_lcm::haptic_patch& chunk);
  void OnPointerSample(const costume_lcm::pointer_sample& sample);
  void OnGuiCommand(const costume_lcm::command& command);
  void OnClothFrame(std::span<const std::uint8_t> payload);
  void ResendCommands();
  void DrainOutgoing();
  void PublishState(const OutgoingDeviceState& state, const GrabState& grab, bool publish_all);
  void PublishStretchRelief(const OutgoingDeviceState& state, const GrabState& grab);
  std::int64_t ToUtime(std::int64_t loop_ns) const;
  std::vector<std::string> CollectWarnings(double elapsed, const PeriodStatistics& periods);

  bus::MessageBus& bus_;
  LoopClock& clock_;
  PatchMailbox& patches_;
  OutgoingQueue& outgoing_;
  DeviceModel model_;
  DeviceLimits limits_;
  WorkspaceTransform workspace_;
  HapticServerIoOptions options_;
  PatchAssembler assembler_;
  GrabTracker grabs_;
  std::shared_ptr<const bus::ReceiveCounts> patch_receive_;
  std::shared_ptr<const bus::ReceiveCounts> pointer_receive_;
  std::shared_ptr<const bus::ReceiveCounts> command_receive_;
  // The sphere radius [m]: radius_ for grab messages and commands; a GUI change arrives in
  // next_radius_ and becomes radius_ while hovering, so a grab keeps the radius it began with.
  // The tick never reads the radius (grab messages are assembled here), so nothing crosses to it.
  double radius_ = 0.05;
  double next_radius_ = 0.05;
  costume_lcm::cloth_frame ack_frame_{};  // decode buffer of OnClothFrame (capacity kept)
  std::vector<std::string> command_warnings_;  // for the next status
  MouseDevice* mouse_ = nullptr;
  bus::Publisher<costume_lcm::device_state> device_state_out_;
  bus::Publisher<costume_lcm::feedback> feedback_out_;
  bus::Publisher<costume_lcm::grab> grab_out_;
  bus::CommandResender command_out_;
  bus::Publisher<costume_lcm::status> status_out_;
  costume_lcm::device_state device_state_msg_{};
  costume_lcm::feedback feedback_msg_{};
  costume_lcm::grab grab_msg_{};
  std::int64_t utime_offset_ = 0;  // epoch µs minus loop-clock µs
  const HapticLoop* loop_ = nullptr;
  const HapticTick* tick_ = nullptr;
  TimedTickHandler* timing_ = nullptr;
  std::int64_t last_status_ns_ = 0;
  std::int64_t last_status_ticks_ = 0;
  std::int64_t last_status_recorded_ = 0;  // loop periods recorded at the last status
  LoopCounters last_loop_counters_;
  std::int64_t last_dropped_outgoing_ = 0;
  PatchAssemblyCounts last_patch_counts_;
  std::int64_t num_transport_failures_ = 0;
  std::int64_t last_pointer_invalid_ = 0;
  HapticServerIoCounts counts_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  /// What Start's thread was refused ("" when granted or not asked); written by the thread
  /// before its first Poll, read by it (status) or after Stop.
  std::string io_priority_refusal_;
  /// KernelPreemptionWarning of this machine, read once: repeated in every status.
  std::string preemption_warning_;
};

}  // namespace costume::haptics
