#include "haptic_server/haptic_server_io.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "bus/channels.h"
#include "sim_core/common/input_error.h"

namespace costume::haptics {

// ---- PatchAssembler ---------------------------------------------------------------------

PatchAssembler::PatchAssembler(const PatchCapacity& capacity) : capacity_(capacity) {
  sim::RequirePositive("patch capacity.max_particles", capacity.max_particles, "particles");
  sim::RequirePositive("patch capacity.max_springs", capacity.max_springs, "springs");
  sim::RequirePositive("patch capacity.max_chunks", capacity.max_chunks, "chunks");
  patch_.Reserve(capacity.max_particles, capacity.max_springs);
  selected_.reserve(static_cast<std::size_t>(capacity.max_particles));
  received_.assign(static_cast<std::size_t>(capacity.max_chunks), 0);
}

bool PatchAssembler::ChunkIsValid(const costume_lcm::haptic_patch& c) const {
  const bool counts_ok = c.num_chunks >= 1 && c.num_chunks <= capacity_.max_chunks &&
                         c.chunk_index >= 0 && c.chunk_index < c.num_chunks &&
                         c.total_particles >= 0 && c.total_particles <= capacity_.max_particles &&
                         c.total_springs >= 0 && c.total_springs <= capacity_.max_springs &&
                         c.num_particles >= 0 && c.num_springs >= 0 && c.first_particle >= 0 &&
                         c.first_spring >= 0;
  if (!counts_ok) return false;
  const std::int64_t particle_end = std::int64_t{c.first_particle} + c.num_particles;
  const std::int64_t spring_end = std::int64_t{c.first_spring} + c.num_springs;
  if (particle_end > c.total_particles || spring_end > c.total_springs) return false;
  return std::isfinite(c.centre[0]) && std::isfinite(c.centre[1]) && std::isfinite(c.centre[2]) &&
         std::isfinite(c.radius) && c.radius > 0.0;
}

bool PatchAssembler::MatchesHeader(const costume_lcm::haptic_patch& c) const {
  const costume_lcm::haptic_patch& h = header_;
  return c.num_chunks == h.num_chunks && c.total_particles == h.total_particles &&
         c.total_springs == h.total_springs && c.model_revision == h.model_revision &&
         c.device_id == h.device_id && c.grab_id == h.grab_id && c.radius == h.radius &&
         c.centre[0] == h.centre[0] && c.centre[1] == h.centre[1] && c.centre[2] == h.centre[2];
}

void PatchAssembler::Start(const costume_lcm::haptic_patch& c) {
  header_.frame = c.frame;
  header_.model_revision = c.model_revision;
  header_.device_id = c.device_id;
  header_.grab_id = c.grab_id;
  std::copy(std::begin(c.centre), std::end(c.centre), std::begin(header_.centre));
  header_.radius = c.radius;
  header_.num_chunks = c.num_chunks;
  header_.total_particles = c.total_particles;
  header_.total_springs = c.total_springs;
  std::fill(received_.begin(), received_.end(), 0);
  num_received_ = 0;
  particles_received_ = 0;
  springs_received_ = 0;
  patch_.positions.resize(static_cast<std::size_t>(c.total_particles));
  patch_.velocities.resize(static_cast<std::size_t>(c.total_particles));
  selected_.assign(static_cast<std::size_t>(c.total_particles), 0);
  patch_.springs.resize(static_cast<std::size_t>(c.total_springs));
  assembling_ = true;
}

void PatchAssembler::Abandon() {
  assembling_ = false;
  num_received_ = 0;
}

void PatchAssembler::CopyChunk(const costume_lcm::haptic_patch& c) {
  for (int i = 0; i < c.num_particles; ++i) {
    const std::size_t k = static_cast<std::size_t>(c.first_particle + i);
    patch_.positions[k] = Eigen::Vector3d(c.x[i], c.y[i], c.z[i]);
    patch_.velocities[k] = Eigen::Vector3d(c.vx[i], c.vy[i], c.vz[i]);
    selected_[k] = c.selected[i] ? 1 : 0;
  }
  for (int i = 0; i < c.num_springs; ++i) {
    PatchSpring& s = patch_.springs[static_cast<std::size_t>(c.first_spring + i)];
    s.a = c.spring_a[i];
    s.b = c.spring_b[i];
    s.stiffness = c.stiffness[i];
    s.damping = c.damping[i];
    s.rest_length = c.rest_length[i];
  }
  particles_received_ += c.num_particles;
  springs_received_ += c.num_springs;
}

bool PatchAssembler::Add(const costume_lcm::haptic_patch& c) {
  if (!ChunkIsValid(c)) {
    ++counts_.num_invalid_chunks;
    return false;
  }
  if (assembling_ && c.frame != header_.frame) {
    ++counts_.num_incomplete;  // the frame being assembled lost a chunk or got mixed
    Abandon();
  }
  if (assembling_ && !MatchesHeader(c)) {
    ++counts_.num_inconsistent;
    Abandon();
    return false;  // neither version of this frame can be trusted
  }
  if (!assembling_) Start(c);
  if (received_[static_cast<std::size_t>(c.chunk_index)] != 0) {
    ++counts_.num_duplicate_chunks;
    return false;
  }
  received_[static_cast<std::size_t>(c.chunk_index)] = 1;
  ++num_received_;
  CopyChunk(c);
  if (num_received_ < header_.num_chunks) return false;
  assembling_ = false;
  if (particles_received_ != header_.total_particles ||
      springs_received_ != header_.total_springs) {
    ++counts_.num_inconsistent;  // chunks overlap or leave a gap
    return false;
  }
  patch_.sequence = static_cast<std::uint64_t>(header_.frame) + 1;
  patch_.centre = Eigen::Vector3d(header_.centre[0], header_.centre[1], header_.centre[2]);
  patch_.radius = header_.radius;
  frame_ = header_.frame;
  grab_id_ = header_.grab_id;
  device_id_ = header_.device_id;
  ++counts_.num_assembled;
  return true;
}

void ApplySelection(HapticPatch& patch, const std::vector<std::uint8_t>& selected) {
  const std::size_t n = patch.positions.size();
  if (!patch.valid || selected.size() != n) return;
  if (std::none_of(selected.begin(), selected.end(), [](std::uint8_t s) { return s != 0; })) {
    return;
  }
  const double variance = GaussianVariance(patch.radius);
  patch.num_selected = 0;
  for (std::size_t i = 0; i < n; ++i) {
    // A selected particle exactly at the Gaussian's tail still counts as selected (weight > 0).
    patch.weights[i] = selected[i] != 0
                           ? std::max(GaussianWeight(patch.positions[i], patch.centre, variance),
                                      std::numeric_limits<double>::min())
                           : 0.0;
    patch.num_selected += selected[i] != 0 ? 1 : 0;
  }
  patch.boundary_springs.clear();
  patch.boundary_signs.clear();
  for (int k = 0; k < static_cast<int>(patch.springs.size()); ++k) {
    const bool a_in = selected[static_cast<std::size_t>(patch.springs[k].a)] != 0;
    const bool b_in = selected[static_cast<std::size_t>(patch.springs[k].b)] != 0;
    if (a_in == b_in) continue;  // internal springs cancel; outside springs do not touch us
    patch.boundary_springs.push_back(k);
    patch.boundary_signs.push_back(a_in ? 1 : -1);
  }
}

// ---- GrabTracker ------------------------------------------------------------------------

const GrabState& GrabTracker::Update(std::uint32_t buttons) {
  const std::uint32_t pressed = buttons & ~last_buttons_;
  const std::uint32_t released = last_buttons_ & ~buttons;
  last_buttons_ = buttons;
  state_.changed = ((pressed | released) & kButtonGrab) != 0;
  state_.stretch_relief_pressed = (pressed & kButtonStretchRelief) != 0;
  if ((pressed & kButtonGrab) != 0) {
    ++state_.grab_id;
    state_.mode = costume_lcm::grab::MODE_GRAB;
  } else if ((released & kButtonGrab) != 0) {
    state_.mode = costume_lcm::grab::MODE_HOVER;
  }
  return state_;
}

// ---- conversions ------------------------------------------------------------------------

std::int8_t DeviceStateModel(DeviceModel model) {
  using M = costume_lcm::device_state;
  switch (model) {
    case DeviceModel::kTouch: return M::MODEL_TOUCH;
    case DeviceModel::kOmni: return M::MODEL_OMNI;
    case DeviceModel::kDesktop: return M::MODEL_DESKTOP;
    case DeviceModel::kCyberGrasp: return M::MODEL_CYBERGRASP;
    case DeviceModel::kSimulated: return M::MODEL_SIMULATED;
    case DeviceModel::kMouse: return M::MODEL_MOUSE;
    case DeviceModel::kLogPlayback: return M::MODEL_PLAYBACK;
  }
  return M::MODEL_SIMULATED;
}

void FeedbackEnvelope(const OutgoingDeviceState& state, std::int8_t& envelope,
                      std::int8_t& fade_reason) {
  using F = costume_lcm::feedback;
  fade_reason = F::FADE_NONE;
  if (state.safety.non_finite) {
    envelope = F::ENVELOPE_FADE_OUT;  // the output is zero at once; say why
    fade_reason = F::FADE_NON_FINITE;
  } else if (state.safety.fading && state.gain > 0.0) {
    envelope = F::ENVELOPE_FADE_OUT;
    fade_reason = state.safety.stale ? F::FADE_STALE_PATCH : F::FADE_RELEASED;
  } else if (state.safety.ramping) {
    envelope = F::ENVELOPE_RAMP_IN;
  } else {
    envelope = state.gain >= 1.0 ? F::ENVELOPE_ON : F::ENVELOPE_OFF;
  }
}

void ToDeviceStateMessage(const OutgoingDeviceState& state, std::int64_t utime, int device_id,
                          DeviceModel model, const DeviceLimits& limits,
                          costume_lcm::device_state& m) {
  m.utime = utime;
  m.device_id = static_cast<std::int8_t>(device_id);
  m.model = DeviceStateModel(model);
  std::copy(state.tip_position.begin(), state.tip_position.end(), m.position);
  std::copy(state.tip_orientation.begin(), state.tip_orientation.end(), m.orientation);
  std::copy(state.tip_velocity.begin(), state.tip_velocity.end(), m.velocity);
  m.buttons = static_cast<std::int32_t>(state.buttons);
  m.force_rendering = state.device_force[0] != 0.0 || state.device_force[1] != 0.0 ||
                      state.device_force[2] != 0.0;
  m.max_force = static_cast<float>(limits.max_force);
  m.max_stiffness = static_cast<float>(limits.max_stiffness);
}

void ToFeedbackMessage(const OutgoingDeviceState& state, std::int64_t utime, int device_id,
                       const WorkspaceTransform& workspace, costume_lcm::feedback& m) {
  m.utime = utime;
  m.device_id = static_cast<std::int8_t>(device_id);
  m.patch_frame = static_cast<std::int64_t>(state.patch_sequence) - 1;
  const Eigen::Vector3d device_force(state.device_force[0], state.device_force[1],
                                     state.device_force[2]);
  const Eigen::Vector3d scene_force = workspace.rotation * device_force;
  for (int i = 0; i < 3; ++i) {
    m.force[i] = scene_force[i];
    m.requested_force[i] = state.feedback_force[static_cast<std::size_t>(i)];
  }
  m.clamped = state.safety.force_clamped || state.safety.stiffness_limited;
  FeedbackEnvelope(state, m.envelope, m.fade_reason);
  m.gain = static_cast<float>(state.gain);
}

void ToGrabMessage(const OutgoingDeviceState& state, const GrabState& grab, std::int64_t utime,
                   int device_id, double radius, double coupling_stiffness,
                   costume_lcm::grab& m) {
  m.coupling_stiffness = coupling_stiffness;
  m.utime = utime;
  m.device_id = static_cast<std::int8_t>(device_id);
  m.mode = grab.mode;
  m.grab_id = grab.grab_id;
  m.buttons = static_cast<std::int32_t>(state.buttons);
  std::copy(state.tip_position.begin(), state.tip_position.end(), m.centre);
  m.radius = radius;
  m.gaussian_sigma = 0.5 * radius;  // grab_forces.h: variance (r/2)²
  const bool grabbing = grab.mode == costume_lcm::grab::MODE_GRAB;
  for (int i = 0; i < 3; ++i) {
    m.force[i] = grabbing ? -state.feedback_force[static_cast<std::size_t>(i)] : 0.0;
  }
}

// ---- TimedTickHandler, ReleasableDevice ------------------------------------------------

void TimedTickHandler::Tick(const TickInfo& info) {
  const std::int64_t start = clock_.Now();
  inner_.Tick(info);
  const std::int64_t work = clock_.Now() - start;
  sum_ns_.fetch_add(work, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
  std::int64_t max = max_ns_.load(std::memory_order_relaxed);
  while (work > max && !max_ns_.compare_exchange_weak(max, work, std::memory_order_relaxed)) {
  }
}

void TimedTickHandler::TakeWorkTimes(std::int64_t& sum_ns, std::int64_t& max_ns,
                                     std::int64_t& count) {
  sum_ns = sum_ns_.exchange(0, std::memory_order_relaxed);
  max_ns = max_ns_.exchange(0, std::memory_order_relaxed);
  count = count_.exchange(0, std::memory_order_relaxed);
}

DeviceFault ReleasableDevice::Read(DeviceState& state) {
  const DeviceFault fault = inner_.Read(state);
  if (released_.load(std::memory_order_relaxed)) state.buttons = 0;
  return fault;
}

// ---- HapticServerIo ---------------------------------------------------------------------

void HapticServerIoOptions::Validate() const {
  sim::RequireInRange("haptic server.radius", radius, kMinRadius, kMaxRadius, "m");
  sim::RequireInRange("haptic server.device_id", device_id, 0, 127, "");
  sim::RequireInRange("haptic server.publish_every", publish_every, 1, 1000, "ticks");
  sim::RequirePositive("haptic server.status_period", status_period, "s");
  sim::RequireInRange("haptic server.io_priority", io_priority, -99, 99, "");
}

namespace {

HapticServerIoOptions Validated(const HapticServerIoOptions& options) {
  options.Validate();
  return options;
}

}  // namespace

HapticServerIo::HapticServerIo(bus::MessageBus& bus, LoopClock& clock, PatchMailbox& patches,
                               OutgoingQueue& outgoing, const HapticDevice& device,
                               const WorkspaceTransform& workspace,
                               const HapticServerIoOptions& options)
    : bus_(bus),
      clock_(clock),
      patches_(patches),
      outgoing_(outgoing),
      model_(device.model()),
      limits_(device.limits()),
      workspace_(workspace),
      options_(Validated(options)),
      assembler_(options.capacity),
      device_state_out_(bus, bus::kDeviceStateChannel),
      feedback_out_(bus, bus::kFeedbackChannel),
      grab_out_(bus, bus::kGrabChannel),
      command_out_(bus, bus::kHapticCommandChannel, options.resend),
      status_out_(bus, bus::kHapticStatusChannel),
      preemption_warning_(KernelPreemptionWarning(ReadKernelPreemption())) {
  workspace_.Validate("haptic server workspace");
  const PatchCapacity& cap = options_.capacity;
  patches_.ForEachSlot([&cap](HapticPatch& slot) { slot.Reserve(cap.max_particles, cap.max_springs); });
  patch_receive_ = bus::Subscribe<costume_lcm::haptic_patch>(
      bus_, bus::kHapticPatchChannel,
      [this](const costume_lcm::haptic_patch& chunk) { OnPatchChunk(chunk); },
      options_.patch_policy);
  command_receive_ = bus::Subscribe<costume_lcm::command>(
      bus_, bus::kCommandChannel,
      [this](const costume_lcm::command& command) { OnGuiCommand(command); },
      options_.command_policy);
  bus_.Subscribe(bus::kClothFrameChannel,
                 [this](std::span<const std::uint8_t> payload) { OnClothFrame(payload); });
  radius_ = next_radius_ = options_.radius;
  const std::int64_t now_ns = clock_.Now();
  utime_offset_ = bus::NowUtime() - now_ns / 1000;
  last_status_ns_ = now_ns;
}

HapticServerIo::~HapticServerIo() { Stop(); }

void HapticServerIo::SetStatusSources(const HapticLoop* loop, const HapticTick* tick,
                                      TimedTickHandler* timing) {
  loop_ = loop;
  tick_ = tick;
  timing_ = timing;
}

std::int64_t HapticServerIo::ToUtime(std::int64_t loop_ns) const {
  return utime_offset_ + loop_ns / 1000;
}

void HapticServerIo::SetPointerDevice(MouseDevice* mouse) {
  if (mouse_ != nullptr || mouse == nullptr) {
    throw sim::InputError("HapticServerIo::SetPointerDevice: needs one mouse device, once");
  }
  mouse_ = mouse;
  pointer_receive_ = bus::Subscribe<costume_lcm::pointer_sample>(
      bus_, bus::kPointerChannel,
      [this](const costume_lcm::pointer_sample& sample) { OnPointerSample(sample); },
      options_.pointer_policy);
}

void HapticServerIo::OnPointerSample(const costume_lcm::pointer_sample& sample) {
  const Eigen::Vector3d scene(sample.position[0], sample.position[1], sample.position[2]);
  if (sample.inside_view && !scene.allFinite()) {
    ++counts_.num_pointer_invalid;
    return;
  }
  MouseSample m;
  m.time = 1e-6 * static_cast<double>(sample.utime);
  m.position = sample.inside_view ? workspace_.PositionToDevice(scene) : Eigen::Vector3d::Zero();
  m.buttons = static_cast<std::uint32_t>(sample.buttons);
  m.inside_view = sample.inside_view;
  mouse_->Push(m);
  ++counts_.num_pointer_samples;
}

void HapticServerIo::OnGuiCommand(const costume_lcm::command& command) {
  if (command.kind != costume_lcm::command::KIND_SET_SELECTION_RADIUS) return;  // the server's
  if (!(command.radius >= kMinRadius && command.radius <= kMaxRadius)) {
    ++counts_.num_radius_refused;
    char line[160];
    std::snprintf(line, sizeof line,
                  "command SET_SELECTION_RADIUS: radius = %g m: must be in [%g, %g] m; kept %g m",
                  command.radius, kMinRadius, kMaxRadius, next_radius_);
    command_warnings_.emplace_back(line);
    return;
  }
  ++counts_.num_radius_commands;
  next_radius_ = command.radius;
  if (grabs_.state().mode != costume_lcm::grab::MODE_GRAB) radius_ = next_radius_;
}

void HapticServerIo::OnClothFrame(std::span<const std::uint8_t> payload) {
  // Frames are the simulation's acknowledgement of device-button commands; decoding every
  // chunk (up to 60 kB at 60 Hz) is wasted work while nothing waits for one.
  if (!command_out_.has_pending()) return;
  if (!bus::Decode(payload, ack_frame_)) return;
  command_out_.Acknowledge(ack_frame_.haptic_command_seq);
}

void HapticServerIo::ResendCommands() {
  if (command_out_.ResendDue(ToUtime(clock_.Now())) > 0) {
    for (const costume_lcm::command& c : command_out_.given_up()) {
      command_warnings_.push_back("command kind " + std::to_string(c.kind) + " seq " +
                                  std::to_string(c.seq) +
                                  " given up: no cloth_frame acknowledged it (is the "
                                  "simulation server running?)");
    }
  }
  counts_.num_commands_resent = command_out_.counts().num_resent;
  counts_.num_commands_given_up = command_out_.counts().num_given_up;
}

void HapticServerIo::OnPatchChunk(const costume_lcm::haptic_patch& chunk) {
  if (!assembler_.Add(chunk)) return;
  PatchAssemblyCounts& counts = assembler_.mutable_counts();
  const GrabState& grab = grabs_.state();
  if (assembler_.device_id() != options_.device_id || assembler_.grab_id() != grab.grab_id ||
      grab.grab_id < 0) {
    ++counts.num_other_grab;
    return;
  }
  // Fill the producer's slot of the triple buffer: the tick never sees it until Publish.
  HapticPatch& slot = patches_.back();
  const HapticPatch& assembled = assembler_.patch();
  slot.sequence = assembled.sequence;
  slot.centre = assembled.centre;
  slot.radius = assembled.radius;
  slot.positions.assign(assembled.positions.begin(), assembled.positions.end());
  slot.velocities.assign(assembled.velocities.begin(), assembled.velocities.end());
  slot.springs.assign(assembled.springs.begin(), assembled.springs.end());
  PreparePatch(slot);
  if (!slot.valid) {
    ++counts.num_invalid_patches;
    return;
  }
  ApplySelection(slot, assembler_.selected());
  slot.arrival_time = static_cast<double>(clock_.Now()) * 1e-9;
  patches_.Publish();
  ++counts_.num_patches_handed;
}

void HapticServerIo::Poll(int timeout_ms) {
  DrainOutgoing();  // first, so a patch arriving now is checked against the latest grab
  if (bus_.HandleSubscriptions(timeout_ms) < 0) ++num_transport_failures_;
  DrainOutgoing();
  ResendCommands();
  const std::int64_t now = clock_.Now();
  if (static_cast<double>(now - last_status_ns_) * 1e-9 >= options_.status_period) {
    PublishStatus();
  }
}

void HapticServerIo::DrainOutgoing() {
  OutgoingDeviceState state;
  while (outgoing_.TryPop(state)) {
    ++counts_.num_states_drained;
    const GrabState& grab = grabs_.Update(state.buttons);
    if (grab.mode != costume_lcm::grab::MODE_GRAB) radius_ = next_radius_;
    const bool due = state.sequence % options_.publish_every == 0;
    if (due || grab.changed) PublishState(state, grab, due);
    if (grab.stretch_relief_pressed) PublishStretchRelief(state, grab);
  }
}

void HapticServerIo::PublishState(const OutgoingDeviceState& state, const GrabState& grab,
                                  bool publish_all) {
  const std::int64_t utime = ToUtime(state.time_ns);
  ToGrabMessage(state, grab, utime, options_.device_id, radius_,
                options_.coupling_stiffness, grab_msg_);
  if (grab_out_.Publish(grab_msg_)) ++counts_.num_grabs_published;
  else ++counts_.num_publish_refused;
  if (!publish_all) return;
  ToDeviceStateMessage(state, utime, options_.device_id, model_, limits_, device_state_msg_);
  if (device_state_out_.Publish(device_state_msg_)) ++counts_.num_device_states_published;
  else ++counts_.num_publish_refused;
  ToFeedbackMessage(state, utime, options_.device_id, workspace_, feedback_msg_);
  if (feedback_out_.Publish(feedback_msg_)) ++counts_.num_feedback_published;
  else ++counts_.num_publish_refused;
}

void HapticServerIo::PublishStretchRelief(const OutgoingDeviceState& state,
                                          const GrabState& grab) {
  costume_lcm::command command{};
  command.utime = ToUtime(state.time_ns);
  command.kind = costume_lcm::command::KIND_ELIMINATE_STRETCH;
  // The selection of the grab being held; hovering, the sphere at the tip.
  command.grab_id = grab.mode == costume_lcm::grab::MODE_GRAB ? grab.grab_id : -1;
  std::copy(state.tip_position.begin(), state.tip_position.end(), command.centre);
  command.radius = radius_;
  if (command_out_.Send(command, command.utime)) ++counts_.num_commands_published;
  else ++counts_.num_publish_refused;
}

std::vector<std::string> HapticServerIo::CollectWarnings(double elapsed,
                                                         const PeriodStatistics& p) {
  std::vector<std::string> warnings;
  char line[256];
  if (loop_ != nullptr) {
    const RealtimeStatus rt = loop_->realtime_status();
    if (!rt.reason.empty()) warnings.push_back("real-time: " + rt.reason);
  }
  if (!preemption_warning_.empty()) warnings.push_back("real-time: " + preemption_warning_);
  if (!io_priority_refusal_.empty()) warnings.push_back(io_priority_refusal_);
  if (loop_ != nullptr) {
    const LoopCounters c = loop_->counters();
    // The fields carry totals since start and the period figures; the per-period counts as text.
    std::snprintf(line, sizeof line,
                  "loop: %lld missed and %lld overruns in the last %.1f s; period p99 %.1f us, "
                  "p99.9 %.1f us, max %.1f us",
                  static_cast<long long>(c.num_missed - last_loop_counters_.num_missed),
                  static_cast<long long>(c.num_overruns - last_loop_counters_.num_overruns),
                  elapsed, p.p99 * 1e-3, p.p999 * 1e-3, p.max * 1e-3);
    warnings.emplace_back(line);
    last_loop_counters_ = c;
  }
  if (tick_ != nullptr) {
    const HapticTickCounters& t = tick_->counters();
    const auto dropped = static_cast<std::int64_t>(t.num_dropped_outgoing);
    if (dropped != last_dropped_outgoing_) {
      std::snprintf(line, sizeof line, "%lld tick states dropped: the I/O thread fell behind",
                    static_cast<long long>(dropped - last_dropped_outgoing_));
      warnings.emplace_back(line);
    }
    last_dropped_outgoing_ = dropped;
    const SafetyCounters& s = tick_->safety().counters();
    std::snprintf(line, sizeof line,
                  "safety: %llu stale ticks, %llu stale episodes, %llu clamped, %llu "
                  "stiffness-limited, %llu non-finite since start",
                  static_cast<unsigned long long>(s.num_stale_steps),
                  static_cast<unsigned long long>(s.num_stale_episodes),
                  static_cast<unsigned long long>(s.num_force_clamped),
                  static_cast<unsigned long long>(s.num_stiffness_limited),
                  static_cast<unsigned long long>(s.num_non_finite));
    warnings.emplace_back(line);
  }
  const PatchAssemblyCounts& a = assembler_.counts();
  const PatchAssemblyCounts& b = last_patch_counts_;
  if (a.num_incomplete != b.num_incomplete || a.num_inconsistent != b.num_inconsistent ||
      a.num_invalid_chunks != b.num_invalid_chunks || a.num_invalid_patches != b.num_invalid_patches ||
      a.num_duplicate_chunks != b.num_duplicate_chunks) {
    std::snprintf(line, sizeof line,
                  "patches dropped since start: %lld incomplete, %lld inconsistent, %lld invalid "
                  "chunks, %lld duplicate chunks, %lld invalid patches, %lld of another grab",
                  static_cast<long long>(a.num_incomplete),
                  static_cast<long long>(a.num_inconsistent),
                  static_cast<long long>(a.num_invalid_chunks),
                  static_cast<long long>(a.num_duplicate_chunks),
                  static_cast<long long>(a.num_invalid_patches),
                  static_cast<long long>(a.num_other_grab));
    warnings.emplace_back(line);
  }
  last_patch_counts_ = a;
  if (counts_.num_pointer_invalid != last_pointer_invalid_) {
    warnings.push_back("pointer samples with a non-finite position dropped since start: " +
                       std::to_string(counts_.num_pointer_invalid));
    last_pointer_invalid_ = counts_.num_pointer_invalid;
  }
  for (std::string& w : command_warnings_) warnings.push_back(std::move(w));
  command_warnings_.clear();
  if (num_transport_failures_ > 0) {
    warnings.push_back("LCM transport failed " + std::to_string(num_transport_failures_) +
                       " times since start");
  }
  return warnings;
}

void HapticServerIo::PublishStatus() {
  const std::int64_t now = clock_.Now();
  const double elapsed = std::max(1e-9, static_cast<double>(now - last_status_ns_) * 1e-9);
  costume_lcm::status status{};
  status.utime = ToUtime(now);
  status.process = "haptic_server";
  status.pid = static_cast<std::int32_t>(::getpid());
  // The periods of this status period only (the ring holds the last minute).
  const std::int64_t recorded = loop_ != nullptr ? loop_->num_recorded() : 0;
  const PeriodStatistics periods =
      loop_ != nullptr ? loop_->StatisticsSince(last_status_recorded_) : PeriodStatistics{};
  last_status_recorded_ = recorded;
  status.period_p50_us = 1e-3 * static_cast<double>(periods.p50);
  status.period_p99_us = 1e-3 * static_cast<double>(periods.p99);
  status.period_p999_us = 1e-3 * static_cast<double>(periods.p999);
  status.period_max_us = 1e-3 * static_cast<double>(periods.max);
  status.target_rate = periods.nominal > 0 ? 1e9 / static_cast<double>(periods.nominal) : 1000.0;
  if (loop_ != nullptr) {
    const LoopCounters c = loop_->counters();
    status.ticks = c.num_ticks;
    status.overruns = c.num_overruns;
    status.missed_ticks = c.num_missed;
    status.measured_rate = static_cast<double>(c.num_ticks - last_status_ticks_) / elapsed;
    last_status_ticks_ = c.num_ticks;
  }
  if (timing_ != nullptr) {
    std::int64_t sum = 0, max = 0, count = 0;
    timing_->TakeWorkTimes(sum, max, count);
    status.frame_time_ms = count > 0 ? 1e-6 * static_cast<double>(sum) / count : 0.0;
    status.max_frame_time_ms = 1e-6 * static_cast<double>(max);
  }
  status.solver_iterations = -1;
  status.mode = costume_lcm::status::MODE_NONE;
  status.playback = costume_lcm::status::PLAYBACK_STOPPED;
  status.frame = -1;
  status.model_revision = -1;
  const bus::ReceiveCounts& r = *patch_receive_;
  const bus::ReceiveCounts q = pointer_receive_counts();
  const bus::ReceiveCounts& c = *command_receive_;
  status.dropped_malformed = r.malformed + q.malformed + c.malformed;
  status.dropped_oversized = r.oversized + q.oversized + c.oversized;
  status.dropped_stale = r.stale + q.stale + c.stale;
  // Includes the GUI's resent copies of commands already taken in (expected, not an alarm).
  status.dropped_out_of_order = r.out_of_order + q.out_of_order + c.out_of_order;
  status.warnings = CollectWarnings(elapsed, periods);
  status.num_warnings = static_cast<std::int16_t>(status.warnings.size());
  if (status_out_.Publish(status)) ++counts_.num_status_published;
  else ++counts_.num_publish_refused;
  last_status_ns_ = now;
}

void HapticServerIo::Start() {
  stop_.store(false);
  thread_ = std::thread([this] {
    if (options_.io_priority > 0) {
      const std::string refused = TryThreadFifoPriority(options_.io_priority);
      io_priority_refusal_ = refused.empty() ? "" : "real-time (I/O thread): " + refused;
    }
    while (!stop_.load(std::memory_order_relaxed)) Poll(2);
  });
}

void HapticServerIo::Stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
  DrainOutgoing();
}

}  // namespace costume::haptics
