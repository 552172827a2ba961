// CommandResender on memq://: copies keep their seq and utime, stop at the acknowledgement,
// give up after max_resends, and a receiver's filter takes each command exactly once.
#include "bus/command_resender.h"

#include <gtest/gtest.h>

#include <vector>

#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "sim_core/common/input_error.h"

namespace costume::bus {
namespace {

using costume_lcm::command;

class ResenderTest : public ::testing::Test {
 protected:
  ResenderTest() {
    ReceivePolicy raw;  // every copy, to count them
    raw.max_age_us = raw.max_lead_us = 0;
    raw.require_increasing_seq = false;
    bus_.Subscribe(kChannel, [this](std::span<const std::uint8_t> payload) {
      command c{};
      ASSERT_TRUE(Decode(payload, c));
      copies_.push_back(c);
    });
    counts_ = Subscribe<command>(bus_, kChannel,
                                 [this](const command& c) { taken_.push_back(c); });
  }
  void Dispatch() {
    while (bus_.HandleSubscriptions(0) > 0) {
    }
  }
  command Make(std::int8_t kind) {
    command c{};
    c.kind = kind;
    c.utime = NowUtime();
    return c;
  }

  static inline const std::string kChannel = "TEST_COMMAND";
  LcmBus bus_{"memq://"};
  std::vector<command> copies_;  // every datagram
  std::vector<command> taken_;   // what a default receive filter accepts
  std::shared_ptr<const ReceiveCounts> counts_;
};

TEST_F(ResenderTest, CopiesKeepSeqAndUtimeAndStopAtTheAcknowledgement) {
  CommandResender r(bus_, kChannel, {100, 5, 8});
  command c = Make(command::KIND_PLAY);
  ASSERT_TRUE(r.Send(c, 1000));
  EXPECT_EQ(r.ResendDue(1099), 0);  // not due yet
  r.ResendDue(1100);
  r.ResendDue(1200);
  r.Acknowledge(0);
  r.ResendDue(1300);
  r.ResendDue(5000);
  Dispatch();
  ASSERT_EQ(copies_.size(), 3u);  // the first copy and two resends; none after the ack
  for (const command& copy : copies_) {
    EXPECT_EQ(copy.seq, 0);
    EXPECT_EQ(copy.utime, c.utime);
  }
  ASSERT_EQ(taken_.size(), 1u);  // the filter took it once, the copies are "out of order"
  EXPECT_EQ(counts_->out_of_order, 2);
  EXPECT_EQ(counts_->sender_restarts, 0);
  EXPECT_EQ(r.counts().num_resent, 2);
  EXPECT_EQ(r.counts().num_acknowledged, 1);
  EXPECT_FALSE(r.has_pending());
}

TEST_F(ResenderTest, GivesUpAfterMaxResendsAndNamesTheCommand) {
  CommandResender r(bus_, kChannel, {100, 2, 8});
  command c = Make(command::KIND_UNDO);
  r.Send(c, 0);
  EXPECT_EQ(r.ResendDue(100), 0);
  EXPECT_EQ(r.ResendDue(200), 0);
  ASSERT_EQ(r.ResendDue(300), 1);
  ASSERT_EQ(r.given_up().size(), 1u);
  EXPECT_EQ(r.given_up()[0].kind, command::KIND_UNDO);
  EXPECT_FALSE(r.has_pending());
  Dispatch();
  EXPECT_EQ(copies_.size(), 3u);  // 1 + max_resends
  EXPECT_EQ(r.counts().num_given_up, 1);
}

// The first copy of command 0 is lost, then command 1 is sent: the resend of 0 goes out
// before 1, so the receiver takes both, in order (an overtaken seq could never be taken in).
TEST_F(ResenderTest, APendingCommandIsResentBeforeANewOne) {
  CommandResender r(bus_, kChannel, {100, 5, 8});
  command first = Make(command::KIND_PLAY);
  r.Send(first, 0);
  Dispatch();
  copies_.clear();
  command second = Make(command::KIND_PAUSE);
  r.Send(second, 10);
  Dispatch();
  ASSERT_EQ(copies_.size(), 2u);
  EXPECT_EQ(copies_[0].seq, 0);
  EXPECT_EQ(copies_[0].kind, command::KIND_PLAY);
  EXPECT_EQ(copies_[1].seq, 1);
  r.Acknowledge(1);  // taking 1 in acknowledges 0 too
  EXPECT_FALSE(r.has_pending());
  EXPECT_EQ(r.counts().num_acknowledged, 2);
}

TEST_F(ResenderTest, KeepsAtMostMaxPendingGivingUpTheOldest) {
  CommandResender r(bus_, kChannel, {100, 5, 2});
  for (int i = 0; i < 3; ++i) {
    command c = Make(command::KIND_PLAY);
    r.Send(c, i);
  }
  ASSERT_EQ(r.given_up().size(), 1u);
  EXPECT_EQ(r.given_up()[0].seq, 0);
  EXPECT_EQ(r.counts().num_given_up, 1);
}

TEST(ResendPolicy, RefusesNonPositivePeriodNegativeResendsAndZeroPending) {
  EXPECT_THROW((ResendPolicy{0, 5, 8}.Validate()), sim::InputError);
  EXPECT_THROW((ResendPolicy{100, -1, 8}.Validate()), sim::InputError);
  EXPECT_THROW((ResendPolicy{100, 5, 0}.Validate()), sim::InputError);
  EXPECT_NO_THROW(ResendPolicy{}.Validate());
}

}  // namespace
}  // namespace costume::bus
