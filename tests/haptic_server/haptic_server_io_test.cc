// The haptic server's I/O on memq://, the tick driven by a FakeClock on the test's thread:
// patch chunks assembled and handed to the tick, incomplete or mixed assemblies dropped and
// counted, the force fading when patches stop, the grab protocol, bad messages counted.
#include "haptic_server/haptic_server_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "haptic_server/mouse_device.h"
#include "haptic_server/simulated_device.h"
#include "sim_core/app/sim_server.h"
#include "tests/support/dropping_bus.h"
#include "tests/support/test_scenes.h"

namespace costume::haptics {
namespace {

constexpr std::int64_t kPeriodNs = 1'000'000;  // 1 kHz

/// A two-particle patch split into two chunks: particle 0 at the sphere centre (selected),
/// particle 1 at (L, 0, 0) outside the sphere, one spring 0–1 of rest length l0 < L.
struct TwoParticlePatch {
  double length = 0.1;       // L [m]
  double rest_length = 0.08; // l0 [m]
  double stiffness = 100.0;  // k [N/m]
  double radius = 0.05;      // r [m]: particle 1 lies outside
  std::int64_t grab_id = 0;

  /// Chunk 0 carries particle 0 and no spring; chunk 1 particle 1 and the spring.
  costume_lcm::haptic_patch Chunk(std::int64_t frame, int index) const {
    costume_lcm::haptic_patch c{};
    c.utime = bus::NowUtime();
    c.frame = frame;
    c.grab_id = grab_id;
    c.radius = radius;
    c.gaussian_sigma = radius / 2;
    c.num_chunks = 2;
    c.chunk_index = static_cast<std::int16_t>(index);
    c.total_particles = 2;
    c.total_springs = 1;
    c.first_particle = index;
    c.num_particles = 1;
    const float x = index == 0 ? 0.0f : static_cast<float>(length);
    c.particle_index = {index};
    c.x = {x};
    c.y = {0.0f};
    c.z = {0.0f};
    c.vx = c.vy = c.vz = {0.0f};
    c.mass = {0.01f};
    c.selected = {index == 0};
    c.weight = {index == 0 ? 1.0f : 0.0f};
    c.first_spring = 0;
    c.num_springs = static_cast<std::int16_t>(index == 1 ? 1 : 0);
    if (index == 1) {
      c.spring_a = {0};
      c.spring_b = {1};
      c.stiffness = {static_cast<float>(stiffness)};
      c.damping = {0.0f};
      c.rest_length = {static_cast<float>(rest_length)};
    }
    return c;
  }
  /// Hand computation: the stretched spring pulls its selected end, particle 0, towards
  /// particle 1 with k (L − l0) along +x; floats as the message carries them.
  double ExpectedFeedbackX() const {
    return static_cast<float>(stiffness) *
           (static_cast<double>(static_cast<float>(length)) -
            static_cast<double>(static_cast<float>(rest_length)));
  }
};

/// Bus, device, tick, loop and I/O on one thread. The simulated hand holds still at the
/// origin of the device frame with the buttons the trajectory scripts.
class IoFixture : public ::testing::Test {
 protected:
  void Build(const std::string& trajectory, int publish_every = 1) {
    device_ = std::make_unique<SimulatedDevice>(ParseTrajectory(trajectory, "test"));
    BuildAround(*device_, publish_every);
  }
  /// The same with the GUI's mouse as the device, fed from COSTUME_POINTER.
  void BuildMouse(int publish_every = 1) {
    mouse_ = std::make_unique<MouseDevice>();
    BuildAround(*mouse_, publish_every);
    io_->SetPointerDevice(mouse_.get());
  }
  void BuildAround(HapticDevice& device, int publish_every) {
    ASSERT_TRUE(device.Open().ok);
    workspace_.scale = 2.0;
    HapticServerIoOptions options;
    options.radius = 0.07;
    options.publish_every = publish_every;
    options.capacity = {1000, 1000, 16};
    options.status_period = 1e9;  // status only when a test asks
    io_ = std::make_unique<HapticServerIo>(*io_bus_, clock_, patches_, outgoing_, device,
                                           workspace_, options);
    tick_ = std::make_unique<HapticTick>(device, patches_, outgoing_, workspace_,
                                         ForceSafetyOptions{});
    HapticLoopOptions loop_options;
    loop_options.realtime_priority = 0;
    loop_options.ring_capacity = 1 << 12;
    loop_ = std::make_unique<HapticLoop>(clock_, *tick_, loop_options);
    io_->SetStatusSources(loop_.get(), tick_.get(), nullptr);
    bus::ReceivePolicy any;  // our own messages: no age check needed
    any.max_age_us = 0;
    any.max_lead_us = 0;
    bus::Subscribe<costume_lcm::feedback>(
        bus_, bus::kFeedbackChannel,
        [this](const costume_lcm::feedback& m) { feedback_.push_back(m); }, any);
    bus::Subscribe<costume_lcm::grab>(
        bus_, bus::kGrabChannel, [this](const costume_lcm::grab& m) { grabs_.push_back(m); },
        any);
    bus::Subscribe<costume_lcm::status>(
        bus_, bus::kHapticStatusChannel,
        [this](const costume_lcm::status& m) { status_.push_back(m); }, any);
  }

  /// Runs `ticks` ticks and lets the I/O thread's work happen after each one.
  void RunTicks(int ticks) {
    for (int i = 0; i < ticks; ++i) {
      io_->Poll(0);  // patches published by the test reach the tick's mailbox
      loop_->Run(1);
      io_->Poll(0);  // the tick's state is published, and dispatched to the test (memq)
    }
  }

  void PublishChunk(const costume_lcm::haptic_patch& chunk) {
    costume_lcm::haptic_patch c = chunk;
    c.seq = patch_seq_++;
    ASSERT_TRUE(bus::Publish(bus_, bus::kHapticPatchChannel, c));
  }
  void PublishPatch(const TwoParticlePatch& patch, std::int64_t frame) {
    PublishChunk(patch.Chunk(frame, 0));
    PublishChunk(patch.Chunk(frame, 1));
  }
  /// The simulation: a fresh patch every 16 ticks (60 Hz) for `ticks` ticks.
  void RunWithPatches(const TwoParticlePatch& patch, int ticks) {
    for (int t = 0; t < ticks; t += 16) {
      PublishPatch(patch, frame_++);
      RunTicks(16);
    }
  }

  bus::LcmBus bus_{"memq://"};
  bus::MessageBus* io_bus_ = &bus_;  // what the server under test publishes on
  FakeClock clock_{1'000'000'000};
  PatchMailbox patches_;
  OutgoingQueue outgoing_;
  WorkspaceTransform workspace_;
  std::unique_ptr<SimulatedDevice> device_;
  std::unique_ptr<MouseDevice> mouse_;
  std::unique_ptr<HapticServerIo> io_;
  std::unique_ptr<HapticTick> tick_;
  std::unique_ptr<HapticLoop> loop_;
  std::vector<costume_lcm::feedback> feedback_;
  std::vector<costume_lcm::grab> grabs_;
  std::vector<costume_lcm::status> status_;
  std::int64_t patch_seq_ = 0;
  std::int64_t frame_ = 100;
};

// The device holds still at its origin, grab button held from t = 0: the tip is at the scene
// origin, where the patch is placed.
constexpr const char* kHoldGrab = "0 0 0 0 1\n";

TEST_F(IoFixture, PatchInTwoChunksReachesTheTickAndItsFeedbackIsTheStretchedSpring) {
  Build(kHoldGrab);
  RunTicks(5);  // the first press: grab 0
  ASSERT_EQ(io_->grab_state().grab_id, 0);
  const TwoParticlePatch patch;
  PublishChunk((patch.Chunk(7, 0)));
  PublishChunk((patch.Chunk(7, 1)));
  feedback_.clear();
  RunTicks(1);
  EXPECT_EQ(io_->counts().patches.num_assembled, 1);
  EXPECT_EQ(io_->counts().num_patches_handed, 1);
  ASSERT_FALSE(feedback_.empty());
  // The first tick with the patch: the tip is exactly at the capture point (u = 0).
  const costume_lcm::feedback& first = feedback_.back();
  EXPECT_EQ(first.patch_frame, 7);
  EXPECT_NEAR(first.requested_force[0], patch.ExpectedFeedbackX(), 1e-9);
  EXPECT_NEAR(patch.ExpectedFeedbackX(), 2.0, 1e-5);  // 100 N/m · 2 cm
  EXPECT_EQ(first.requested_force[1], 0.0);
  EXPECT_EQ(first.requested_force[2], 0.0);

  // Keep the "simulation" sending it at 60 Hz: after the 200 ms ramp the hand feels it.
  RunWithPatches(patch, 300);
  const costume_lcm::feedback& last = feedback_.back();
  EXPECT_EQ(last.envelope, costume_lcm::feedback::ENVELOPE_ON);
  EXPECT_GT(last.force[0], 0.5);  // towards the stretched spring's far end, +x
  EXPECT_LT(last.force[0], 2.0 + 1e-6);
  // The grab carries F_h = −feedback: the hand pulls the cloth the other way.
  ASSERT_FALSE(grabs_.empty());
  EXPECT_EQ(grabs_.back().mode, costume_lcm::grab::MODE_GRAB);
  EXPECT_NEAR(grabs_.back().force[0], -feedback_.back().requested_force[0], 1e-12);
}

TEST_F(IoFixture, TheSimulationsSelectionFlagsDecideWhichSpringsPullTheHand) {
  Build(kHoldGrab);
  RunTicks(2);
  // Particle 1 lies outside the sphere but the simulation still holds it (it was inside when
  // the grab started): both ends are held, the spring is internal and pulls nobody's hand.
  const TwoParticlePatch patch;
  costume_lcm::haptic_patch held = patch.Chunk(1, 1);
  held.selected = {true};
  PublishChunk(patch.Chunk(1, 0));
  PublishChunk(held);
  RunTicks(1);
  ASSERT_EQ(feedback_.back().patch_frame, 1);
  EXPECT_EQ(feedback_.back().requested_force[0], 0.0);
  // The same patch without flags anywhere falls back to the distance test: 2 N again.
  costume_lcm::haptic_patch unflagged0 = patch.Chunk(2, 0);
  costume_lcm::haptic_patch unflagged1 = patch.Chunk(2, 1);
  unflagged0.selected = {false};
  PublishChunk(unflagged0);
  PublishChunk(unflagged1);
  RunTicks(1);
  ASSERT_EQ(feedback_.back().patch_frame, 2);
  EXPECT_NEAR(feedback_.back().requested_force[0], patch.ExpectedFeedbackX(), 1e-9);
}

TEST_F(IoFixture, MissingChunkOrMixedFramesAreDroppedAndCounted) {
  Build(kHoldGrab);
  RunTicks(2);
  const TwoParticlePatch patch;
  // Frame 1 loses its chunk 1; frame 2's chunk 1 arrives without its chunk 0.
  PublishChunk((patch.Chunk(1, 0)));
  PublishChunk((patch.Chunk(2, 1)));
  RunTicks(3);
  EXPECT_EQ(io_->counts().patches.num_assembled, 0);
  EXPECT_EQ(io_->counts().patches.num_incomplete, 1);
  // Frame 3 complete: frame 2 is given up, frame 3 goes through.
  PublishChunk((patch.Chunk(3, 0)));
  PublishChunk((patch.Chunk(3, 1)));
  RunTicks(1);
  EXPECT_EQ(io_->counts().patches.num_incomplete, 2);
  EXPECT_EQ(io_->counts().patches.num_assembled, 1);
  EXPECT_EQ(io_->counts().num_patches_handed, 1);
  EXPECT_EQ(feedback_.back().patch_frame, 3);
  // Same frame, different totals: inconsistent, neither chunk used.
  costume_lcm::haptic_patch other = (patch.Chunk(4, 1));
  other.radius = 0.06;
  PublishChunk((patch.Chunk(4, 0)));
  PublishChunk(other);
  RunTicks(1);
  EXPECT_EQ(io_->counts().patches.num_inconsistent, 1);
  EXPECT_EQ(io_->counts().num_patches_handed, 1);
  // Nothing of frames 1, 2 or 4 ever reached the tick.
  for (const costume_lcm::feedback& f : feedback_) {
    EXPECT_TRUE(f.patch_frame == -1 || f.patch_frame == 3) << f.patch_frame;
  }
}

TEST_F(IoFixture, FeedbackFadesToZeroWithinFiftyMillisecondsOfTheLastPatch) {
  Build(kHoldGrab);
  RunTicks(2);
  const TwoParticlePatch patch;
  RunWithPatches(patch, 320);
  ASSERT_GT(feedback_.back().force[0], 0.5);
  PublishPatch(patch, frame_++);  // the last one
  const std::size_t last_with_patch = feedback_.size();
  // The patches stop. 20 ms later (before stale_after, 25 ms) the force is still there...
  RunTicks(20);
  EXPECT_GT(feedback_.back().force[0], 0.1);
  // ...and from 50 ms on it is exactly zero, reported as off.
  RunTicks(31);
  const costume_lcm::feedback& faded = feedback_.back();
  EXPECT_EQ(faded.force[0], 0.0);
  EXPECT_EQ(faded.force[1], 0.0);
  EXPECT_EQ(faded.force[2], 0.0);
  EXPECT_EQ(faded.gain, 0.0f);
  EXPECT_EQ(faded.envelope, costume_lcm::feedback::ENVELOPE_OFF);
  bool saw_stale_fade = false;
  for (std::size_t i = last_with_patch; i < feedback_.size(); ++i) {
    saw_stale_fade |= feedback_[i].fade_reason == costume_lcm::feedback::FADE_STALE_PATCH;
  }
  EXPECT_TRUE(saw_stale_fade);
  EXPECT_EQ(device_->applied_force(), Eigen::Vector3d::Zero());
}

TEST_F(IoFixture, EachPressStartsANewGrabAtTheTipAndReleaseHovers) {
  // Tip at device (0.01, 0.02, 0.03): scene 2× that (workspace scale 2). Two presses, each
  // between two of the 50-tick publishing points.
  Build("0   0.01 0.02 0.03 0\n"
        "0.1105 0.01 0.02 0.03 0\n0.1105 0.01 0.02 0.03 1\n"
        "0.3105 0.01 0.02 0.03 1\n0.3105 0.01 0.02 0.03 0\n"
        "0.5105 0.01 0.02 0.03 0\n0.5105 0.01 0.02 0.03 1\n"
        "0.7105 0.01 0.02 0.03 1\n0.7105 0.01 0.02 0.03 0\n",
        /*publish_every=*/50);
  RunTicks(900);
  // Collapse consecutive messages of one (mode, grab_id).
  std::vector<std::pair<int, std::int64_t>> phases;
  for (const costume_lcm::grab& g : grabs_) {
    const std::pair<int, std::int64_t> phase(g.mode, g.grab_id);
    if (phases.empty() || phases.back() != phase) phases.push_back(phase);
    EXPECT_NEAR(g.centre[0], 0.02, 1e-12);
    EXPECT_NEAR(g.centre[1], 0.04, 1e-12);
    EXPECT_NEAR(g.centre[2], 0.06, 1e-12);
    EXPECT_EQ(g.radius, 0.07);
    EXPECT_EQ(g.gaussian_sigma, 0.035);
    EXPECT_EQ(g.mode == costume_lcm::grab::MODE_GRAB, (g.buttons & 1) != 0);
  }
  using G = costume_lcm::grab;
  const std::vector<std::pair<int, std::int64_t>> expected = {
      {G::MODE_HOVER, -1}, {G::MODE_GRAB, 0}, {G::MODE_HOVER, 0}, {G::MODE_GRAB, 1},
      {G::MODE_HOVER, 1}};
  EXPECT_EQ(phases, expected);
  // Presses and releases go out on their tick even between the 50-tick decimation: 900 / 50
  // periodic messages plus 4 transitions.
  EXPECT_EQ(grabs_.size(), 18u + 4u);
  // seq numbers the channel.
  for (std::size_t i = 0; i < grabs_.size(); ++i) EXPECT_EQ(grabs_[i].seq, std::int64_t(i));
}

TEST_F(IoFixture, MalformedStaleAndInvalidMessagesAreCountedWithoutACrash) {
  Build(kHoldGrab);
  RunTicks(2);
  const TwoParticlePatch patch;
  // Not a haptic_patch at all.
  const std::vector<std::uint8_t> garbage = {1, 2, 3, 4, 5, 6, 7};
  bus_.Publish(bus::kHapticPatchChannel, garbage);
  // Stamped an hour ago.
  costume_lcm::haptic_patch stale = (patch.Chunk(1, 0));
  stale.utime -= 3'600'000'000;
  PublishChunk(stale);
  // chunk_index outside [0, num_chunks); totals beyond capacity; a non-finite radius.
  costume_lcm::haptic_patch bad_index = (patch.Chunk(2, 0));
  bad_index.chunk_index = 5;
  PublishChunk(bad_index);
  costume_lcm::haptic_patch huge = (patch.Chunk(3, 0));
  huge.total_particles = 1'000'000;
  PublishChunk(huge);
  costume_lcm::haptic_patch nan_radius = (patch.Chunk(4, 0));
  nan_radius.radius = std::nan("");
  PublishChunk(nan_radius);
  // A spring end out of range: assembles, then PreparePatch refuses it.
  costume_lcm::haptic_patch bad_spring = (patch.Chunk(5, 1));
  bad_spring.spring_b = {9};
  PublishChunk((patch.Chunk(5, 0)));
  PublishChunk(bad_spring);
  // A patch of a grab that is not the current one.
  TwoParticlePatch other = patch;
  other.grab_id = 3;
  PublishChunk((other.Chunk(6, 0)));
  PublishChunk((other.Chunk(6, 1)));
  RunTicks(3);

  const PatchAssemblyCounts& c = io_->counts().patches;
  EXPECT_EQ(io_->patch_receive_counts().malformed, 1);
  EXPECT_EQ(io_->patch_receive_counts().stale, 1);
  EXPECT_EQ(c.num_invalid_chunks, 3);
  EXPECT_EQ(c.num_invalid_patches, 1);
  EXPECT_EQ(c.num_other_grab, 1);
  EXPECT_EQ(io_->counts().num_patches_handed, 0);
  for (const costume_lcm::feedback& f : feedback_) EXPECT_EQ(f.patch_frame, -1);

  io_->PublishStatus();
  io_->Poll(0);
  ASSERT_EQ(status_.size(), 1u);
  EXPECT_EQ(status_[0].process, "haptic_server");
  EXPECT_EQ(status_[0].dropped_malformed, 1);
  EXPECT_EQ(status_[0].dropped_stale, 1);
  EXPECT_EQ(status_[0].ticks, 5);
  EXPECT_DOUBLE_EQ(status_[0].target_rate, 1000.0);
  bool mentions_patches = false;
  for (const std::string& w : status_[0].warnings) {
    mentions_patches |= w.find("patches dropped") != std::string::npos;
  }
  EXPECT_TRUE(mentions_patches);

  // And a good patch still goes through afterwards.
  PublishChunk((patch.Chunk(7, 0)));
  PublishChunk((patch.Chunk(7, 1)));
  RunTicks(1);
  EXPECT_EQ(io_->counts().num_patches_handed, 1);
}

// Status carries the loop's period figures of its own status period. Scripted wake-up
// latencies (as haptic_loop_test): 40 µs late on ticks 100..109 and 300 µs late on tick 500
// give periods 1.04/0.96 ms and 1.3/0.7 ms among 1,999 of 1 ms: by hand, p50 = p99 = 1 ms,
// p99.9 (rank 1998 of 1999) = 1.04 ms, max 1.3 ms. Then a wake-up 2.5 ms late: two deadlines
// skipped (missed_ticks 2), a 3.5 ms period, then 0.5 ms, in the second period only.
TEST_F(IoFixture, StatusCarriesTheLoopPeriodFiguresOfEachStatusPeriod) {
  Build(kHoldGrab);
  std::vector<std::int64_t> latency(2000, 0);
  latency[500] = 300'000;
  for (int k = 100; k < 110; ++k) latency[k] = 40'000;
  clock_.ScriptLatencies(latency.data(), 2000);
  loop_->Run(2000);
  io_->PublishStatus();
  io_->Poll(0);
  ASSERT_EQ(status_.size(), 1u);
  EXPECT_DOUBLE_EQ(status_[0].period_p50_us, 1000.0);
  EXPECT_DOUBLE_EQ(status_[0].period_p99_us, 1000.0);
  EXPECT_DOUBLE_EQ(status_[0].period_p999_us, 1040.0);
  EXPECT_DOUBLE_EQ(status_[0].period_max_us, 1300.0);
  EXPECT_EQ(status_[0].missed_ticks, 0);

  std::vector<std::int64_t> late(200, 0);
  late[50] = 2'500'000;
  clock_.ScriptLatencies(late.data(), 200);
  loop_->Run(200);
  io_->PublishStatus();
  io_->Poll(0);
  ASSERT_EQ(status_.size(), 2u);
  EXPECT_EQ(status_[1].missed_ticks, 2);
  EXPECT_DOUBLE_EQ(status_[1].period_max_us, 3500.0);
  EXPECT_DOUBLE_EQ(status_[1].period_p999_us, 3500.0);  // rank 199 of 199
  EXPECT_DOUBLE_EQ(status_[1].period_p99_us, 1000.0);   // rank 198: below the 3.5 ms one
  EXPECT_DOUBLE_EQ(status_[1].period_p50_us, 1000.0);
}

// The GUI's mouse as the device: pointer samples (scene frame) on COSTUME_POINTER, through the
// receive filter, into the MouseDevice the tick reads like any other device. A scripted
// sequence hovers over the patch, presses, pulls 1 cm along −x while the "simulation" keeps
// sending patches, and leaves the view. By hand: the selected particle moves with the tip,
// so the spring to particle 1 is 0.11 m long against a rest length of 0.08 m: feedback
// k·0.03 = 3 N along +x, and the grab carries F_h = −3 N.
TEST_F(IoFixture, PointerSamplesDriveTheMouseDeviceAndTheGrabFollows) {
  BuildMouse();
  bus::Publisher<costume_lcm::pointer_sample> pointer(bus_, bus::kPointerChannel);
  auto send = [&](double x, int buttons, bool inside) {
    costume_lcm::pointer_sample p{};
    p.utime = bus::NowUtime();
    p.position[0] = x;
    p.buttons = buttons;
    p.inside_view = inside;
    ASSERT_TRUE(pointer.Publish(p));
  };
  RunTicks(3);
  EXPECT_TRUE(grabs_.empty() || grabs_.back().mode == costume_lcm::grab::MODE_HOVER);
  send(0.0, 0, true);  // hover at the patch's centre
  RunTicks(3);
  ASSERT_FALSE(grabs_.empty());
  EXPECT_EQ(grabs_.back().mode, costume_lcm::grab::MODE_HOVER);
  EXPECT_EQ(grabs_.back().centre[0], 0.0);
  send(0.0, 1, true);  // press
  RunTicks(2);
  EXPECT_EQ(grabs_.back().mode, costume_lcm::grab::MODE_GRAB);
  EXPECT_EQ(grabs_.back().grab_id, 0);
  const TwoParticlePatch patch;
  // Pull: 1 mm per 16-tick frame for 10 frames, the patch sent each frame as the simulation
  // would (its centre stays where the grab started: the local model is the tick's).
  for (int k = 1; k <= 10; ++k) {
    send(-0.001 * k, 1, true);
    PublishPatch(patch, frame_++);
    RunTicks(16);
    EXPECT_NEAR(grabs_.back().centre[0], -0.001 * k, 1e-15) << k;
    EXPECT_EQ(grabs_.back().grab_id, 0);
  }
  // Hold there through the 200 ms ramp.
  RunWithPatches(patch, 300);
  const double expected = static_cast<float>(patch.stiffness) *
                          (0.01 + static_cast<float>(patch.length) -
                           static_cast<double>(static_cast<float>(patch.rest_length)));
  EXPECT_NEAR(feedback_.back().requested_force[0], expected, 1e-6);
  EXPECT_NEAR(expected, 3.0, 1e-5);
  EXPECT_NEAR(grabs_.back().force[0], -expected, 1e-6);
  EXPECT_EQ(grabs_.back().mode, costume_lcm::grab::MODE_GRAB);
  EXPECT_GT(feedback_.back().force[0], 2.0);  // the ramp is done
  // The pointer leaves the view: no data, buttons released, the grab ends and the force
  // fades to zero.
  send(0.0, 1, false);
  RunWithPatches(patch, 64);
  EXPECT_EQ(grabs_.back().mode, costume_lcm::grab::MODE_HOVER);
  EXPECT_EQ(feedback_.back().force[0], 0.0);
  EXPECT_GT(tick_->counters().num_read_faults[static_cast<int>(DeviceFault::kNoData)], 0);
  EXPECT_EQ(io_->counts().num_pointer_samples, 13);  // hover, press, 10 pulls, leave
  // A non-finite sample inside the view is dropped and counted; a stale one is filtered.
  send(std::nan(""), 1, true);
  costume_lcm::pointer_sample old{};
  old.utime = bus::NowUtime() - 5'000'000;
  old.inside_view = true;
  pointer.Publish(old);
  RunTicks(2);
  EXPECT_EQ(io_->counts().num_pointer_invalid, 1);
  EXPECT_EQ(io_->pointer_receive_counts().stale, 1);
  io_->PublishStatus();
  io_->Poll(0);
  ASSERT_FALSE(status_.empty());
  EXPECT_EQ(status_.back().dropped_stale, 1);
  // Back in the view and pressed again: a new grab.
  send(0.0, 1, true);
  RunTicks(2);
  EXPECT_EQ(grabs_.back().mode, costume_lcm::grab::MODE_GRAB);
  EXPECT_EQ(grabs_.back().grab_id, 1);
}

// ---- commands: resent until acknowledged; the GUI's selection radius --------------------

// The stretch-relief button's command loses its first datagram; a real simulation server
// (memq://, stepped every 16 ticks) still applies it exactly once (model revision +1), and
// nothing is resent after a cloth_frame's haptic_command_seq acknowledged it.
TEST_F(IoFixture, AStretchCommandWhoseFirstCopyIsLostIsAppliedOnceAndNotResentAfterItsAck) {
  testing::DroppingBus lossy(bus_, bus::kHapticCommandChannel, 1);
  io_bus_ = &lossy;
  // Device (0.25, 0, -0.25) is scene (0.5, 0, -0.5) (scale 2): the 17×17 sheet's pinned
  // corner, whose neighbours (1/16 m) stay inside the 0.07 m sphere while the sheet falls.
  // Stretch button at 50 ms.
  Build("0 0.25 0 -0.25 0\n0.0505 0.25 0 -0.25 0\n0.0505 0.25 0 -0.25 2\n"
        "0.2 0.25 0 -0.25 2\n0.2 0.25 0 -0.25 0\n");
  const sim_app::SimServerOptions server_options;  // named: GCC 12 warns on a temporary
  sim_app::SimServer server(bus_, test::HangScene(17), server_options);
  const std::int64_t revision0 = server.model_revision();
  auto run = [&](int ticks) {
    for (int t = 0; t < ticks; ++t) {
      RunTicks(1);
      if (t % 16 == 0) server.Step();  // 60 Hz
    }
  };
  run(400);
  EXPECT_EQ(server.model_revision(), revision0 + 1);
  EXPECT_EQ(lossy.published(), 2);  // the lost copy and one resend 100 ms later
  EXPECT_EQ(io_->counts().num_commands_resent, 1);
  EXPECT_EQ(io_->counts().num_commands_given_up, 0);
  run(1000);  // a second: no resend after the acknowledgement, no second application
  EXPECT_EQ(lossy.published(), 2);
  EXPECT_EQ(server.model_revision(), revision0 + 1);
}

// Without a simulation server nothing acknowledges: five resends 100 ms apart, then a
// warning in status naming the command.
TEST_F(IoFixture, AnUnacknowledgedCommandIsGivenUpWithAWarningInStatus) {
  testing::DroppingBus counting(bus_, bus::kHapticCommandChannel, 0);
  io_bus_ = &counting;
  Build("0 0 0 0 0\n0.0105 0 0 0 0\n0.0105 0 0 0 2\n0.05 0 0 0 2\n0.05 0 0 0 0\n");
  RunTicks(1000);
  EXPECT_EQ(counting.published(), 6);
  EXPECT_EQ(io_->counts().num_commands_given_up, 1);
  io_->PublishStatus();
  io_->Poll(0);
  ASSERT_FALSE(status_.empty());
  bool warned = false;
  for (const std::string& w : status_.back().warnings) {
    warned = warned || w.find("given up") != std::string::npos;
  }
  EXPECT_TRUE(warned);
}

// SET_SELECTION_RADIUS on COSTUME_COMMAND: taken while hovering at once; during a grab the
// grab keeps its radius and the new one applies from the next grab; out of range is refused.
TEST_F(IoFixture, TheGuisSelectionRadiusAppliesFromTheNextGrab) {
  // Grab held 0.1–0.3 s and again from 0.5 s.
  Build("0 0 0 0 0\n0.1005 0 0 0 0\n0.1005 0 0 0 1\n0.3005 0 0 0 1\n0.3005 0 0 0 0\n"
        "0.5005 0 0 0 0\n0.5005 0 0 0 1\n");
  bus::Publisher<costume_lcm::command> gui(bus_, bus::kCommandChannel);
  auto set_radius = [&](double r) {
    costume_lcm::command c{};
    c.utime = bus::NowUtime();
    c.kind = costume_lcm::command::KIND_SET_SELECTION_RADIUS;
    c.radius = r;
    ASSERT_TRUE(gui.Publish(c));
  };
  RunTicks(50);
  set_radius(0.12);  // hovering: at once
  RunTicks(100);     // t = 150 ms, grabbing
  EXPECT_EQ(io_->radius(), 0.12);
  set_radius(0.2);  // during the grab: kept for the next one
  set_radius(20.0);  // out of range (above 10 m): refused
  RunTicks(100);    // t = 250 ms, still grabbing
  EXPECT_EQ(io_->radius(), 0.12);
  RunTicks(400);    // released at 300 ms, grabbing again from 500 ms
  EXPECT_EQ(io_->radius(), 0.2);
  EXPECT_EQ(io_->counts().num_radius_commands, 2);
  EXPECT_EQ(io_->counts().num_radius_refused, 1);
  // What the simulation was told: grab 0 at 0.12 m throughout, grab 1 at 0.2 m.
  for (const costume_lcm::grab& g : grabs_) {
    if (g.mode != costume_lcm::grab::MODE_GRAB) continue;
    EXPECT_EQ(g.radius, g.grab_id == 0 ? 0.12 : 0.2) << "grab " << g.grab_id;
    EXPECT_EQ(g.gaussian_sigma, g.radius / 2);
  }
}

TEST(GrabTracker, RisingEdgesNumberGrabsAndStretchReliefIsAnEdge) {
  GrabTracker t;
  EXPECT_EQ(t.Update(0).grab_id, -1);
  EXPECT_TRUE(t.Update(kButtonGrab).changed);
  EXPECT_EQ(t.state().grab_id, 0);
  EXPECT_FALSE(t.Update(kButtonGrab).changed);
  EXPECT_TRUE(t.Update(kButtonGrab | kButtonStretchRelief).stretch_relief_pressed);
  EXPECT_FALSE(t.Update(kButtonGrab | kButtonStretchRelief).stretch_relief_pressed);
  EXPECT_EQ(t.Update(0).mode, costume_lcm::grab::MODE_HOVER);
  EXPECT_EQ(t.Update(kButtonGrab).grab_id, 1);
}

}  // namespace
}  // namespace costume::haptics
