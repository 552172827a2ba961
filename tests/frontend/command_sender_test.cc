// The GUI's CommandSender on memq://: a command whose first datagram is lost is resent and
// applied exactly once by a real simulation server, and not resent after a cloth_frame's
// command_seq acknowledged it; SET_SELECTION_RADIUS carries the radius.
#include "frontend/command_sender.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "sim_core/app/sim_server.h"
#include "tests/support/dropping_bus.h"
#include "tests/support/test_scenes.h"

namespace costume::frontend {
namespace {

TEST(CommandSender, AStretchCommandWhoseFirstCopyIsLostIsAppliedOnceAndNotResentAfterItsAck) {
  bus::LcmBus bus("memq://");
  testing::DroppingBus lossy(bus, bus::kCommandChannel, 1);
  bus::ResendPolicy resend;
  resend.period_us = 1000;  // 1 ms: the test need not wait 100 ms
  CommandSender sender(lossy, resend);
  const sim_app::SimServerOptions server_options;  // named: GCC 12 warns on a temporary
  sim_app::SimServer server(bus, test::HangScene(17), server_options);
  // What the window does with each chunk (MainWindow::OnClothChunk).
  bus::Subscribe<costume_lcm::cloth_frame>(
      bus, bus::kClothFrameChannel,
      [&sender](const costume_lcm::cloth_frame& chunk) { sender.Acknowledge(chunk.command_seq); });
  const std::int64_t revision0 = server.model_revision();
  // A node of the sheet's top edge with its 1/16 m neighbours in the sphere.
  ASSERT_TRUE(sender.EliminateStretch(Eigen::Vector3d(0, 0, -0.5), 0.07));
  auto run = [&](int frames) {
    for (int i = 0; i < frames; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // a resend period passes
      EXPECT_TRUE(sender.ResendDue().empty());
      server.Step();
      while (bus.HandleSubscriptions(0) > 0) {
      }
    }
  };
  run(3);
  EXPECT_EQ(server.model_revision(), revision0 + 1);
  EXPECT_EQ(lossy.published(), 2);  // the lost copy and one resend
  EXPECT_EQ(sender.resend_counts().num_resent, 1);
  EXPECT_EQ(sender.resend_counts().num_acknowledged, 1);
  run(5);  // acknowledged: no more copies, no second application
  EXPECT_EQ(lossy.published(), 2);
  EXPECT_EQ(server.model_revision(), revision0 + 1);
  EXPECT_EQ(server.ignored().commands_refused, 0);
}

TEST(CommandSender, SetSelectionRadiusCarriesTheRadiusAndTheSimulationIgnoresItSilently) {
  bus::LcmBus bus("memq://");
  CommandSender sender(bus);
  std::vector<costume_lcm::command> received;
  bus::Subscribe<costume_lcm::command>(
      bus, bus::kCommandChannel,
      [&received](const costume_lcm::command& c) { received.push_back(c); });
  const sim_app::SimServerOptions server_options;  // named: GCC 12 warns on a temporary
  sim_app::SimServer server(bus, test::HangScene(9), server_options);
  ASSERT_TRUE(sender.SetSelectionRadius(0.125));
  server.Step();
  while (bus.HandleSubscriptions(0) > 0) {
  }
  ASSERT_EQ(received.size(), 1u);
  EXPECT_EQ(received[0].kind, costume_lcm::command::KIND_SET_SELECTION_RADIUS);
  EXPECT_EQ(received[0].radius, 0.125);
  EXPECT_EQ(server.ignored().commands_refused, 0);
}

}  // namespace
}  // namespace costume::frontend
