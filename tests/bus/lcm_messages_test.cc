// Every message type of lcm_types/ survives encode → memq:// → decode with every field
// equal; the wire layout and the chunk sizes match hand computation.
#include <gtest/gtest.h>

#include <cstring>
#include <optional>

#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/device_state.hpp"
#include "lcm_types/costume_lcm/feedback.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"
#include "lcm_types/costume_lcm/status.hpp"

namespace costume::bus {
namespace {

// Stamps near now, so that the default receive policy accepts them.
const std::int64_t kUtime = NowUtime();

// Publishes `sent` on memq:// and returns what the typed subscriber received.
template <class Message>
std::optional<Message> RoundTrip(const Message& sent, const std::string& channel) {
  LcmBus bus("memq://");
  std::optional<Message> received;
  auto counts = Subscribe<Message>(bus, channel, [&](const Message& m) { received = m; });
  EXPECT_TRUE(Publish(bus, channel, sent));
  EXPECT_EQ(bus.HandleSubscriptions(100), 1);
  EXPECT_EQ(counts->accepted, 1);
  EXPECT_EQ(counts->dropped(), 0);
  return received;
}

template <class T, std::size_t N>
void ExpectArrayEq(const T (&a)[N], const T (&b)[N]) {
  for (std::size_t i = 0; i < N; ++i) EXPECT_EQ(a[i], b[i]) << "index " << i;
}

TEST(LcmMessages, DeviceStateRoundTrips) {
  costume_lcm::device_state s{};
  s.utime = kUtime;
  s.seq = 7;
  s.device_id = 2;
  s.model = costume_lcm::device_state::MODEL_DESKTOP;
  const double position[3] = {0.1, -0.25, 1.5};
  const double orientation[4] = {0.5, -0.5, 0.5, 0.5};
  const double velocity[3] = {-0.01, 0.02, 0.3};
  std::memcpy(s.position, position, sizeof position);
  std::memcpy(s.orientation, orientation, sizeof orientation);
  std::memcpy(s.velocity, velocity, sizeof velocity);
  s.buttons = 0b101;
  s.force_rendering = 1;
  s.max_force = 7.9f;
  s.max_stiffness = 1000.0f;
  const auto r = RoundTrip(s, kDeviceStateChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 7);
  EXPECT_EQ(r->device_id, 2);
  EXPECT_EQ(r->model, 5);
  ExpectArrayEq(r->position, position);
  ExpectArrayEq(r->orientation, orientation);
  ExpectArrayEq(r->velocity, velocity);
  EXPECT_EQ(r->buttons, 5);
  EXPECT_EQ(r->force_rendering, 1);
  EXPECT_EQ(r->max_force, 7.9f);
  EXPECT_EQ(r->max_stiffness, 1000.0f);
}

TEST(LcmMessages, GrabRoundTrips) {
  costume_lcm::grab g{};
  g.utime = kUtime;
  g.seq = 11;
  g.device_id = 1;
  g.mode = costume_lcm::grab::MODE_GRAB;
  g.grab_id = 42;
  g.buttons = 1;
  const double centre[3] = {0.0, 1.2, -0.05};
  const double force[3] = {0.5, -1.25, 2.0};
  std::memcpy(g.centre, centre, sizeof centre);
  std::memcpy(g.force, force, sizeof force);
  g.radius = 0.04;
  g.gaussian_sigma = 0.02;
  const auto r = RoundTrip(g, kGrabChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 11);
  EXPECT_EQ(r->device_id, 1);
  EXPECT_EQ(r->mode, 1);
  EXPECT_EQ(r->grab_id, 42);
  EXPECT_EQ(r->buttons, 1);
  ExpectArrayEq(r->centre, centre);
  ExpectArrayEq(r->force, force);
  EXPECT_EQ(r->radius, 0.04);
  EXPECT_EQ(r->gaussian_sigma, 0.02);
}

TEST(LcmMessages, FeedbackRoundTrips) {
  costume_lcm::feedback f{};
  f.utime = kUtime;
  f.seq = 3;
  f.device_id = 0;
  f.patch_frame = 1234;
  const double force[3] = {3.3, 0.0, -0.1};
  const double requested[3] = {5.0, 0.25, -0.15};
  std::memcpy(f.force, force, sizeof force);
  std::memcpy(f.requested_force, requested, sizeof requested);
  f.clamped = 1;
  f.envelope = costume_lcm::feedback::ENVELOPE_FADE_OUT;
  f.fade_reason = costume_lcm::feedback::FADE_NON_FINITE;
  f.gain = 0.375f;
  const auto r = RoundTrip(f, kFeedbackChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 3);
  EXPECT_EQ(r->device_id, 0);
  EXPECT_EQ(r->patch_frame, 1234);
  ExpectArrayEq(r->force, force);
  ExpectArrayEq(r->requested_force, requested);
  EXPECT_EQ(r->clamped, 1);
  EXPECT_EQ(r->envelope, 3);
  EXPECT_EQ(r->fade_reason, 3);
  EXPECT_EQ(r->gain, 0.375f);
}

costume_lcm::cloth_frame MakeFrame(int num_particles) {
  costume_lcm::cloth_frame c{};
  c.utime = kUtime;
  c.seq = 99;
  c.frame = 600;
  c.sim_time = 10.0;
  c.model_revision = 4;
  c.mode = costume_lcm::cloth_frame::MODE_EDITING;
  c.total_particles = 12'000;
  c.chunk_index = 1;
  c.num_chunks = 3;
  c.first_particle = 5000;
  c.num_particles = static_cast<std::int16_t>(num_particles);
  for (int i = 0; i < num_particles; ++i) {
    c.x.push_back(0.001f * i);
    c.y.push_back(-0.5f + 0.002f * i);
    c.z.push_back(1.0f / (i + 1));
  }
  return c;
}

TEST(LcmMessages, ClothFrameRoundTrips) {
  const auto c = MakeFrame(3);
  const auto r = RoundTrip(c, kClothFrameChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 99);
  EXPECT_EQ(r->frame, 600);
  EXPECT_EQ(r->sim_time, 10.0);
  EXPECT_EQ(r->model_revision, 4);
  EXPECT_EQ(r->mode, 1);
  EXPECT_EQ(r->total_particles, 12'000);
  EXPECT_EQ(r->chunk_index, 1);
  EXPECT_EQ(r->num_chunks, 3);
  EXPECT_EQ(r->first_particle, 5000);
  EXPECT_EQ(r->num_particles, 3);
  ASSERT_EQ(r->x.size(), 3u);
  EXPECT_EQ(r->x, c.x);
  EXPECT_EQ(r->y, c.y);
  EXPECT_EQ(r->z, c.z);
}

costume_lcm::haptic_patch MakePatch(int num_particles, int num_springs) {
  costume_lcm::haptic_patch p{};
  p.utime = kUtime;
  p.seq = 5;
  p.frame = 601;
  p.model_revision = 4;
  p.device_id = 1;
  p.grab_id = 42;
  p.centre[0] = 0.1;
  p.centre[1] = 1.1;
  p.centre[2] = -0.2;
  p.radius = 0.05;
  p.gaussian_sigma = 0.025;
  p.chunk_index = 0;
  p.num_chunks = 2;
  p.total_particles = 1000;
  p.total_springs = 3000;
  p.first_particle = 0;
  p.first_spring = 0;
  p.num_particles = static_cast<std::int16_t>(num_particles);
  for (int i = 0; i < num_particles; ++i) {
    p.particle_index.push_back(100 + 3 * i);
    p.x.push_back(0.01f * i);
    p.y.push_back(1.0f + 0.01f * i);
    p.z.push_back(-0.01f * i);
    p.vx.push_back(0.5f);
    p.vy.push_back(-0.25f * i);
    p.vz.push_back(0.125f);
    p.mass.push_back(0.001f * (i + 1));
    p.selected.push_back(i % 2);
    p.weight.push_back(i % 2 ? 1.0f / (i + 1) : 0.0f);
  }
  p.num_springs = static_cast<std::int16_t>(num_springs);
  for (int s = 0; s < num_springs; ++s) {
    p.spring_a.push_back(s % num_particles);
    p.spring_b.push_back((s + 1) % num_particles);
    p.stiffness.push_back(1000.0f + s);
    p.damping.push_back(1.0f + 0.5f * s);
    p.rest_length.push_back(0.01f * (s + 1));
  }
  return p;
}

TEST(LcmMessages, HapticPatchRoundTrips) {
  const auto p = MakePatch(3, 2);
  const auto r = RoundTrip(p, kHapticPatchChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 5);
  EXPECT_EQ(r->frame, 601);
  EXPECT_EQ(r->model_revision, 4);
  EXPECT_EQ(r->device_id, 1);
  EXPECT_EQ(r->grab_id, 42);
  ExpectArrayEq(r->centre, p.centre);
  EXPECT_EQ(r->radius, 0.05);
  EXPECT_EQ(r->gaussian_sigma, 0.025);
  EXPECT_EQ(r->chunk_index, 0);
  EXPECT_EQ(r->num_chunks, 2);
  EXPECT_EQ(r->total_particles, 1000);
  EXPECT_EQ(r->total_springs, 3000);
  EXPECT_EQ(r->first_particle, 0);
  EXPECT_EQ(r->first_spring, 0);
  EXPECT_EQ(r->num_particles, 3);
  EXPECT_EQ(r->particle_index, (std::vector<std::int32_t>{100, 103, 106}));
  EXPECT_EQ(r->x, p.x);
  EXPECT_EQ(r->y, p.y);
  EXPECT_EQ(r->z, p.z);
  EXPECT_EQ(r->vx, p.vx);
  EXPECT_EQ(r->vy, p.vy);
  EXPECT_EQ(r->vz, p.vz);
  EXPECT_EQ(r->mass, p.mass);
  EXPECT_EQ(r->selected, (std::vector<std::int8_t>{0, 1, 0}));
  EXPECT_EQ(r->weight, p.weight);
  EXPECT_EQ(r->num_springs, 2);
  EXPECT_EQ(r->spring_a, (std::vector<std::int32_t>{0, 1}));
  EXPECT_EQ(r->spring_b, (std::vector<std::int32_t>{1, 2}));
  EXPECT_EQ(r->stiffness, p.stiffness);
  EXPECT_EQ(r->damping, p.damping);
  EXPECT_EQ(r->rest_length, p.rest_length);
}

TEST(LcmMessages, CommandRoundTripsWithNestedParameters) {
  costume_lcm::command c{};
  c.utime = kUtime;
  c.seq = 2;
  c.kind = costume_lcm::command::KIND_SET_MATERIAL;
  c.database_id = 17;
  c.name = "denim, washed";
  c.mode = costume_lcm::command::MODE_EDITING;
  c.garment = -1;
  c.material = {"heavy_denim", 0.4, 2000.0, 1500.0, 2e-5, 2e-3, 0.03, 0.6, 0.0, 12.5, 0.0};
  c.solver.method = costume_lcm::solver_parameters::METHOD_MULTIGRID;
  c.solver.levels = 3;
  c.solver.tolerance = 1e-3;
  c.solver.max_iterations = 200;
  c.solver.substeps = 4;
  c.solver.strain_limit = 0.05;
  c.grab_id = 42;
  c.centre[0] = -0.1;
  c.centre[1] = 0.9;
  c.centre[2] = 0.3;
  c.radius = 0.06;
  const auto r = RoundTrip(c, kCommandChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 2);
  EXPECT_EQ(r->kind, 8);
  EXPECT_EQ(r->database_id, 17);
  EXPECT_EQ(r->name, "denim, washed");
  EXPECT_EQ(r->mode, 1);
  EXPECT_EQ(r->garment, -1);
  EXPECT_EQ(r->material.name, "heavy_denim");
  EXPECT_EQ(r->material.density, 0.4);
  EXPECT_EQ(r->material.stretch_stiffness, 2000.0);
  EXPECT_EQ(r->material.shear_stiffness, 1500.0);
  EXPECT_EQ(r->material.bending_rigidity, 2e-5);
  EXPECT_EQ(r->material.damping, 2e-3);
  EXPECT_EQ(r->material.air_drag, 0.03);
  EXPECT_EQ(r->material.friction, 0.6);
  EXPECT_EQ(r->material.structural_spring_k, 0.0);
  EXPECT_EQ(r->material.shear_spring_k, 12.5);
  EXPECT_EQ(r->material.bending_spring_k, 0.0);
  EXPECT_EQ(r->solver.method, 2);
  EXPECT_EQ(r->solver.levels, 3);
  EXPECT_EQ(r->solver.tolerance, 1e-3);
  EXPECT_EQ(r->solver.max_iterations, 200);
  EXPECT_EQ(r->solver.substeps, 4);
  EXPECT_EQ(r->solver.strain_limit, 0.05);
  EXPECT_EQ(r->grab_id, 42);
  ExpectArrayEq(r->centre, c.centre);
  EXPECT_EQ(r->radius, 0.06);
}

TEST(LcmMessages, StatusRoundTripsWithWarnings) {
  costume_lcm::status s{};
  s.utime = kUtime;
  s.seq = 60;
  s.process = "haptic_server";
  s.pid = 4321;
  s.target_rate = 1000.0;
  s.measured_rate = 999.5;
  s.frame_time_ms = 0.04;
  s.max_frame_time_ms = 0.5;
  s.ticks = 60'000;
  s.overruns = 3;
  s.solver_iterations = -1;
  s.mode = costume_lcm::status::MODE_NONE;
  s.playback = costume_lcm::status::PLAYBACK_PAUSED;
  s.frame = -1;
  s.sim_time = 0.0;
  s.model_revision = 9;
  s.undo_depth = 2;
  s.redo_depth = 1;
  s.dropped_malformed = 10;
  s.dropped_oversized = 11;
  s.dropped_stale = 12;
  s.dropped_out_of_order = 13;
  s.num_warnings = 2;
  s.warnings = {"real-time priority refused", ""};
  const auto r = RoundTrip(s, kHapticStatusChannel);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->utime, kUtime);
  EXPECT_EQ(r->seq, 60);
  EXPECT_EQ(r->process, "haptic_server");
  EXPECT_EQ(r->pid, 4321);
  EXPECT_EQ(r->target_rate, 1000.0);
  EXPECT_EQ(r->measured_rate, 999.5);
  EXPECT_EQ(r->frame_time_ms, 0.04);
  EXPECT_EQ(r->max_frame_time_ms, 0.5);
  EXPECT_EQ(r->ticks, 60'000);
  EXPECT_EQ(r->overruns, 3);
  EXPECT_EQ(r->solver_iterations, -1);
  EXPECT_EQ(r->mode, -1);
  EXPECT_EQ(r->playback, 2);
  EXPECT_EQ(r->frame, -1);
  EXPECT_EQ(r->sim_time, 0.0);
  EXPECT_EQ(r->model_revision, 9);
  EXPECT_EQ(r->undo_depth, 2);
  EXPECT_EQ(r->redo_depth, 1);
  EXPECT_EQ(r->dropped_malformed, 10);
  EXPECT_EQ(r->dropped_oversized, 11);
  EXPECT_EQ(r->dropped_stale, 12);
  EXPECT_EQ(r->dropped_out_of_order, 13);
  EXPECT_EQ(r->num_warnings, 2);
  EXPECT_EQ(r->warnings, (std::vector<std::string>{"real-time priority refused", ""}));
}

// LCM's wire format (lcm type specification): 8-byte fingerprint, then the fields in
// declaration order, big-endian. Checked on bytes, independently of the generated decode.
TEST(LcmMessages, EncodingIsBigEndianFieldsAfterTheFingerprint) {
  costume_lcm::grab g{};
  g.utime = 0x0102030405060708;
  g.seq = 9;
  std::vector<std::uint8_t> bytes(g.getEncodedSize());
  ASSERT_EQ(g.encode(bytes.data(), 0, static_cast<int>(bytes.size())), bytes.size());
  auto big_endian = [&](int offset) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v = (v << 8) | bytes[offset + i];
    return v;
  };
  EXPECT_EQ(big_endian(0), static_cast<std::uint64_t>(costume_lcm::grab::getHash()));
  EXPECT_EQ(big_endian(8), 0x0102030405060708u);
  EXPECT_EQ(big_endian(16), 9u);
  // grab: hash 8, utime 8, seq 8, device_id 1, mode 1, grab_id 8, buttons 4, centre 24,
  // radius 8, sigma 8, force 24, coupling stiffness 8.
  EXPECT_EQ(bytes.size(), 8u + 8 + 8 + 1 + 1 + 8 + 4 + 24 + 8 + 8 + 24 + 8);
}

// A full chunk fits one UDP datagram (channel name + 1 + payload <= 65,499 bytes).
TEST(LcmMessages, FullChunksFitOneDatagram) {
  const int n = costume_lcm::cloth_frame::MAX_PARTICLES_PER_CHUNK;
  const auto frame = MakeFrame(n);
  // Hand count: hash, utime, seq, frame, sim_time, model_revision 6×8; mode 1; the three
  // input seqs 3×8; total 4; chunk_index 2, num_chunks 2; first 4; num 2; x, y, z 12 per
  // particle.
  EXPECT_EQ(frame.getEncodedSize(), 48 + 1 + 24 + 4 + 2 + 2 + 4 + 2 + 12 * n);
  EXPECT_LE(frame.getEncodedSize(), MaxDatagramPayload(kClothFrameChannel));
  EXPECT_EQ(MaxDatagramPayload(kClothFrameChannel), 65'499 - 19 - 1);

  const int np = costume_lcm::haptic_patch::MAX_PARTICLES_PER_CHUNK;
  const int ns = costume_lcm::haptic_patch::MAX_SPRINGS_PER_CHUNK;
  const auto patch = MakePatch(np, ns);
  // Hand count: 8-byte fields hash, utime, seq, frame, model_revision, grab_id, radius,
  // sigma (8×8) + centre 24; device_id 1; chunk_index, num_chunks 2×2; four int32 totals
  // and offsets 16; two int16 counts 4; 37 bytes per particle, 20 per spring.
  EXPECT_EQ(patch.getEncodedSize(), 64 + 24 + 1 + 4 + 16 + 4 + 37 * np + 20 * ns);
  EXPECT_LE(patch.getEncodedSize(), MaxDatagramPayload(kHapticPatchChannel));
}

}  // namespace
}  // namespace costume::bus
