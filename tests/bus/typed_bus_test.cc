// Typed publish/subscribe on memq://: malformed, oversized, stale and out-of-order messages
// are counted and dropped, never handed over and never a crash; Publisher numbers messages.
#include <gtest/gtest.h>

#include <climits>
#include <random>
#include <vector>

#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/device_state.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"

namespace costume::bus {
namespace {

constexpr std::int64_t kNow = 1'700'000'000'000'000;  // a fixed "now" [µs since the epoch]
const std::string kChannel = "COSTUME_TEST";

costume_lcm::cloth_frame Frame(std::int64_t utime, std::int64_t seq, int num_particles) {
  costume_lcm::cloth_frame frame{};
  frame.utime = utime;
  frame.seq = seq;
  frame.num_chunks = 1;
  frame.num_particles = static_cast<std::int16_t>(num_particles);
  frame.total_particles = num_particles;
  frame.x.assign(num_particles, 0.5f);
  frame.y.assign(num_particles, 1.5f);
  frame.z.assign(num_particles, -0.5f);
  return frame;
}

std::vector<std::uint8_t> Encode(const costume_lcm::cloth_frame& frame) {
  std::vector<std::uint8_t> bytes(frame.getEncodedSize());
  EXPECT_EQ(frame.encode(bytes.data(), 0, static_cast<int>(bytes.size())), bytes.size());
  return bytes;
}

// A memq:// bus with one cloth_frame subscription on a fixed clock.
struct Fixture {
  explicit Fixture(ReceivePolicy policy = {}) {
    if (!policy.clock) policy.clock = [] { return kNow; };
    counts = Subscribe<costume_lcm::cloth_frame>(
        bus, kChannel, [this](const costume_lcm::cloth_frame& m) { received.push_back(m); },
        std::move(policy));
  }
  // Publishes raw bytes and handles them; returns how many messages were dispatched.
  int Deliver(const std::vector<std::uint8_t>& bytes) {
    EXPECT_TRUE(bus.Publish(kChannel, bytes));
    return bus.HandleSubscriptions(100);
  }
  LcmBus bus{"memq://"};
  std::shared_ptr<const ReceiveCounts> counts;
  std::vector<costume_lcm::cloth_frame> received;
};

TEST(TypedBus, DropsMalformedPayloadsWithoutCrashing) {
  Fixture f;
  const auto valid = Encode(Frame(kNow, 0, 4));
  std::vector<std::vector<std::uint8_t>> bad;
  bad.push_back({});                                          // empty
  bad.push_back({1, 2, 3});                                   // shorter than a fingerprint
  bad.push_back(std::vector<std::uint8_t>(100, 0xAB));        // noise: wrong fingerprint
  bad.push_back({valid.begin(), valid.end() - 1});            // truncated
  auto trailing = valid;
  trailing.push_back(0);                                      // trailing byte
  bad.push_back(trailing);
  {
    costume_lcm::grab grab{};                                 // another type on this channel
    grab.utime = kNow;
    std::vector<std::uint8_t> bytes(grab.getEncodedSize());
    grab.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    bad.push_back(bytes);
  }
  // num_particles (int16, big-endian) sits after hash 8, utime/seq/frame/sim_time/
  // model_revision 40, mode 1, the three input seqs 24, total 4, chunk_index 2,
  // num_chunks 2, first_particle 4.
  constexpr int kCountOffset = 8 + 40 + 1 + 24 + 4 + 2 + 2 + 4;
  for (std::int16_t count : {std::int16_t{-1}, std::int16_t{-32768}, std::int16_t{32767},
                             std::int16_t{5}}) {
    auto patched = valid;
    patched[kCountOffset] = static_cast<std::uint8_t>((count >> 8) & 0xFF);
    patched[kCountOffset + 1] = static_cast<std::uint8_t>(count & 0xFF);
    bad.push_back(patched);
  }
  for (const auto& bytes : bad) EXPECT_EQ(f.Deliver(bytes), 1);
  EXPECT_EQ(f.counts->malformed, static_cast<std::int64_t>(bad.size()));
  EXPECT_EQ(f.counts->accepted, 0);
  EXPECT_TRUE(f.received.empty());
  // The untouched message still gets through afterwards.
  f.Deliver(valid);
  ASSERT_EQ(f.received.size(), 1u);
  EXPECT_EQ(f.received[0].x, std::vector<float>(4, 0.5f));
}

TEST(TypedBus, SurvivesRandomlyCorruptedMessages) {
  Fixture f(ReceivePolicy{.require_increasing_seq = false});
  costume_lcm::haptic_patch patch{};
  patch.utime = kNow;
  patch.num_particles = 40;
  patch.particle_index.assign(40, 7);
  for (auto* v : {&patch.x, &patch.y, &patch.z, &patch.vx, &patch.vy, &patch.vz, &patch.mass,
                  &patch.weight}) {
    v->assign(40, 0.25f);
  }
  patch.selected.assign(40, 1);
  patch.num_springs = 60;
  patch.spring_a.assign(60, 1);
  patch.spring_b.assign(60, 2);
  for (auto* v : {&patch.stiffness, &patch.damping, &patch.rest_length}) v->assign(60, 1.0f);
  std::vector<std::uint8_t> valid(patch.getEncodedSize());
  ASSERT_EQ(patch.encode(valid.data(), 0, static_cast<int>(valid.size())), valid.size());

  LcmBus& bus = f.bus;
  std::int64_t accepted = 0;
  auto counts = Subscribe<costume_lcm::haptic_patch>(
      bus, "COSTUME_PATCH_TEST",
      [&](const costume_lcm::haptic_patch& m) {
        ++accepted;
        EXPECT_TRUE(CountsMatch(m));  // decoded arrays always agree with their counts
      },
      ReceivePolicy{.require_increasing_seq = false, .clock = [] { return kNow; }});
  std::mt19937 random(12345);
  constexpr int kMessages = 3000;
  for (int i = 0; i < kMessages; ++i) {
    auto bytes = valid;
    const int flips = 1 + static_cast<int>(random() % 4);
    for (int k = 0; k < flips; ++k) {
      // Past the fingerprint (else nearly everything fails there).
      bytes[8 + random() % (bytes.size() - 8)] ^= static_cast<std::uint8_t>(1u << (random() % 8));
    }
    if (random() % 5 == 0) bytes.resize(random() % bytes.size());
    ASSERT_TRUE(bus.Publish("COSTUME_PATCH_TEST", bytes));
    bus.HandleSubscriptions(100);
  }
  EXPECT_EQ(counts->accepted + counts->dropped(), kMessages);
  EXPECT_EQ(counts->accepted, accepted);
  EXPECT_GT(counts->malformed, 0);
  EXPECT_GT(counts->stale, 0);  // flips in utime
  EXPECT_GT(counts->accepted, 0);  // flips in float payloads decode fine
}

TEST(TypedBus, DropsOversizedMessagesUndecoded) {
  Fixture limited(ReceivePolicy{.max_bytes = 130});
  // 87 bytes of header + 12 per particle (lcm_messages_test.cc): 3 particles = 123 bytes.
  limited.Deliver(Encode(Frame(kNow, 0, 3)));
  limited.Deliver(Encode(Frame(kNow, 1, 4)));  // 135 bytes
  EXPECT_EQ(limited.counts->accepted, 1);
  EXPECT_EQ(limited.counts->oversized, 1);

  Fixture by_default;  // limit: one UDP datagram on this channel
  const int limit = 65'499 - static_cast<int>(kChannel.size()) - 1;
  by_default.Deliver(std::vector<std::uint8_t>(limit + 1, 0));
  by_default.Deliver(std::vector<std::uint8_t>(limit, 0));  // within the limit: malformed
  EXPECT_EQ(by_default.counts->oversized, 1);
  EXPECT_EQ(by_default.counts->malformed, 1);
}

TEST(TypedBus, DropsStaleAndFutureMessages) {
  Fixture f(ReceivePolicy{.max_age_us = 1'000'000, .max_lead_us = 2'000,
                          .require_increasing_seq = false});
  f.Deliver(Encode(Frame(kNow - 1'000'001, 0, 1)));  // 1 µs too old
  f.Deliver(Encode(Frame(kNow - 1'000'000, 1, 1)));  // exactly at the limit: kept
  f.Deliver(Encode(Frame(kNow + 2'001, 2, 1)));      // 1 µs too far ahead
  f.Deliver(Encode(Frame(kNow + 2'000, 3, 1)));
  f.Deliver(Encode(Frame(INT64_MIN, 4, 1)));         // extremes must not overflow
  f.Deliver(Encode(Frame(INT64_MAX, 5, 1)));
  f.Deliver(Encode(Frame(0, 6, 1)));
  EXPECT_EQ(f.counts->stale, 5);
  EXPECT_EQ(f.counts->accepted, 2);
  ASSERT_EQ(f.received.size(), 2u);
  EXPECT_EQ(f.received[0].seq, 1);
  EXPECT_EQ(f.received[1].seq, 3);

  Fixture replay(ReceivePolicy{.max_age_us = 0, .max_lead_us = 0});  // checks off
  replay.Deliver(Encode(Frame(0, 0, 1)));
  replay.Deliver(Encode(Frame(INT64_MAX, 1, 1)));
  EXPECT_EQ(replay.counts->accepted, 2);
}

TEST(TypedBus, DropsOutOfOrderAndDuplicateMessagesButFollowsARestartedSender) {
  Fixture f;
  f.Deliver(Encode(Frame(kNow - 500, 5, 1)));
  f.Deliver(Encode(Frame(kNow - 400, 6, 1)));
  f.Deliver(Encode(Frame(kNow - 400, 6, 1)));  // duplicate
  f.Deliver(Encode(Frame(kNow - 600, 4, 1)));  // late
  f.Deliver(Encode(Frame(kNow - 300, 8, 1)));  // a gap is fine (a lost datagram)
  f.Deliver(Encode(Frame(kNow - 350, 7, 1)));  // late
  EXPECT_EQ(f.counts->out_of_order, 3);
  EXPECT_EQ(f.counts->accepted, 3);
  // The sender restarts: seq back to 0, newer utime.
  f.Deliver(Encode(Frame(kNow - 100, 0, 1)));
  f.Deliver(Encode(Frame(kNow - 50, 1, 1)));
  EXPECT_EQ(f.counts->sender_restarts, 1);
  EXPECT_EQ(f.counts->accepted, 5);
  EXPECT_EQ(f.counts->dropped(), 3);
  std::vector<std::int64_t> seqs;
  for (const auto& m : f.received) seqs.push_back(m.seq);
  EXPECT_EQ(seqs, (std::vector<std::int64_t>{5, 6, 8, 0, 1}));
}

TEST(TypedBus, PublisherNumbersMessagesAndRefusesBadOnes) {
  Fixture f;
  Publisher<costume_lcm::cloth_frame> publisher(f.bus, kChannel);
  auto good = Frame(kNow, 99, 2);
  EXPECT_TRUE(publisher.Publish(good));
  EXPECT_EQ(good.seq, 0);
  auto mismatched = Frame(kNow, 0, 2);
  mismatched.num_particles = 3;  // x, y, z hold 2: encode would read past them
  EXPECT_FALSE(publisher.Publish(mismatched));
  auto negative = Frame(kNow, 0, 0);
  negative.num_particles = -1;
  EXPECT_FALSE(publisher.Publish(negative));
  auto huge = Frame(kNow, 0, 6000);  // 72,063 bytes: more than one datagram
  EXPECT_FALSE(publisher.Publish(huge));
  EXPECT_EQ(publisher.num_refused(), 3);
  EXPECT_TRUE(publisher.Publish(good));
  EXPECT_TRUE(publisher.Publish(good));
  EXPECT_EQ(publisher.next_seq(), 3);
  while (f.bus.HandleSubscriptions(50) > 0) {
  }
  std::vector<std::int64_t> seqs;
  for (const auto& m : f.received) seqs.push_back(m.seq);
  EXPECT_EQ(seqs, (std::vector<std::int64_t>{0, 1, 2}));
  EXPECT_EQ(f.counts->dropped(), 0);
}

TEST(TypedBus, CountsAreKeptPerSubscription) {
  LcmBus bus("memq://");
  int states = 0;
  auto device_counts = Subscribe<costume_lcm::device_state>(
      bus, "COSTUME_DEVICE", [&](const costume_lcm::device_state&) { ++states; },
      ReceivePolicy{.clock = [] { return kNow; }});
  Fixture f;  // another bus: nothing crosses
  costume_lcm::device_state state{};
  state.utime = kNow;
  EXPECT_TRUE(Publish(bus, "COSTUME_DEVICE", state));
  EXPECT_TRUE(bus.Publish("COSTUME_DEVICE", std::vector<std::uint8_t>{1, 2}));
  while (bus.HandleSubscriptions(50) > 0) {
  }
  EXPECT_EQ(states, 1);
  EXPECT_EQ(device_counts->accepted, 1);
  EXPECT_EQ(device_counts->malformed, 1);
  EXPECT_EQ(f.counts->accepted + f.counts->dropped(), 0);
}

}  // namespace
}  // namespace costume::bus
