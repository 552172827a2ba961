// The 60 Hz simulation server driven frame by frame (Step) on LCM's in-process memq://
// provider: the test plays the haptic server and the GUI, publishing grabs and commands and
// reading back cloth frames, haptic patches and status. Oracles are computed from the
// published messages and the model independently of the server's own bookkeeping.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <limits>
#include <string>
#include <set>
#include <tuple>
#include <vector>

#include "assets/scene_file.h"
#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/settings_codec.h"
#include "bus/typed_bus.h"
#include "sim_core/app/sim_server.h"
#include "sim_core/avatar/hanim.h"
#include "tests/support/test_scenes.h"

namespace costume::sim_app {
namespace {

using costume_lcm::command;
using costume_lcm::grab;

// ---- the loop's deadline arithmetic, by hand -------------------------------------------

TEST(NextDeadline, OnTimeFramesKeepTheGrid) {
  EXPECT_EQ(NextDeadline(0, 5, 10).next, 10);
  EXPECT_EQ(NextDeadline(0, 5, 10).missed, 0);
  EXPECT_EQ(NextDeadline(0, 10, 10).next, 10);  // finished exactly at the deadline: on time
  EXPECT_EQ(NextDeadline(0, 10, 10).missed, 0);
}

TEST(NextDeadline, AnOverrunSkipsToTheNextFutureDeadlineAndCountsTheMissedOnes) {
  // Frame due at 0 ran until 21: deadlines 10 and 20 passed; the next is 30.
  EXPECT_EQ(NextDeadline(0, 21, 10).next, 30);
  EXPECT_EQ(NextDeadline(0, 21, 10).missed, 2);
  EXPECT_EQ(NextDeadline(100, 111, 10).next, 120);
  EXPECT_EQ(NextDeadline(100, 111, 10).missed, 1);
}

// A loop on a fake clock: frames of 4, 4, 25, 4, 4 ms work at a 10 ms period. Lag never
// accumulates: after the long frame the wake-ups return to the 10 ms grid.
TEST(NextDeadline, AFakeClockLoopReturnsToTheGridAfterALongFrame) {
  const std::int64_t period = 10;
  const std::vector<std::int64_t> work = {4, 4, 25, 4, 4};
  std::int64_t deadline = 0;
  std::int64_t overruns = 0;
  std::vector<std::int64_t> wakeups;
  for (std::int64_t w : work) {
    wakeups.push_back(deadline);
    const Deadline next = NextDeadline(deadline, deadline + w, period);
    overruns += next.missed;
    deadline = next.next;  // the fake sleep returns exactly at the deadline
  }
  // The frame woken at 20 ends at 45: 30 and 40 are missed, the next wake-up is 50.
  EXPECT_EQ(wakeups, (std::vector<std::int64_t>{0, 10, 20, 50, 60}));
  EXPECT_EQ(overruns, 2);
}

// ---- the server on memq:// --------------------------------------------------------------

sim::SceneDescription SoftHang() {
  sim::Material soft;
  soft.name = "soft";
  soft.stretch_stiffness = soft.shear_stiffness = 20.0;  // N/m: a 1/4 N grab stretches cm
  soft.bending_rigidity = 1e-6;
  sim::SceneDescription scene = test::HangScene(17, soft);
  scene.solver.strain_limit = 0.0;
  scene.solver.tolerance = 1e-4;
  return scene;
}

constexpr int kSettleFrames = 600;
constexpr int kBottomMiddle = 16 * 17 + 8;

/// What the server published, assembled from the chunks.
struct Received {
  std::int64_t frame = -1;
  std::int64_t revision = -1;
  std::int8_t mode = -1;
  sim::Points positions;  ///< of the last frame (n×3) [m], as published (float)
  std::vector<costume_lcm::haptic_patch> patch;  ///< chunks of the last patch
  std::int64_t num_patch_chunks = 0;             ///< every patch chunk ever received
  std::vector<costume_lcm::status> statuses;
};

class SimServerTest : public ::testing::Test {
 protected:
  explicit SimServerTest(sim::SceneDescription scene = SoftHang(), SimServerOptions options = {})
      : bus_("memq://") {
    bus::Subscribe<costume_lcm::cloth_frame>(
        bus_, bus::kClothFrameChannel, [this](const costume_lcm::cloth_frame& m) {
          received_.frame = m.frame;
          received_.revision = m.model_revision;
          received_.mode = m.mode;
          received_.positions.resize(m.total_particles, 3);
          for (int i = 0; i < m.num_particles; ++i) {
            received_.positions.row(m.first_particle + i) << m.x[i], m.y[i], m.z[i];
          }
        });
    bus::Subscribe<costume_lcm::haptic_patch>(
        bus_, bus::kHapticPatchChannel, [this](const costume_lcm::haptic_patch& m) {
          if (m.chunk_index == 0) received_.patch.clear();
          received_.patch.push_back(m);
          ++received_.num_patch_chunks;
        });
    bus::Subscribe<costume_lcm::status>(
        bus_, bus::kSimStatusChannel,
        [this](const costume_lcm::status& m) { received_.statuses.push_back(m); });
    server_ = std::make_unique<SimServer>(bus_, std::move(scene), options);
  }

  /// Steps the server `n` frames, collecting what it publishes.
  void Step(int n = 1) {
    for (int i = 0; i < n; ++i) {
      server_->Step();
      bus_.HandleSubscriptions(0);
    }
  }

  void SendCommand(command c) {
    c.utime = bus::NowUtime();
    command_publisher_.Publish(c);
  }
  void SendMode(std::int8_t mode) {
    command c{};
    c.kind = command::KIND_SET_MODE;
    c.mode = mode;
    SendCommand(c);
  }
  void SendKind(std::int8_t kind) {
    command c{};
    c.kind = kind;
    SendCommand(c);
  }

  /// A pressed grab of device 0 at `centre` [m], radius [m], force [N].
  static grab MakeGrab(std::int64_t id, const Eigen::Vector3d& centre, double radius,
                       const Eigen::Vector3d& force) {
    grab g{};
    g.device_id = 0;
    g.mode = grab::MODE_GRAB;
    g.grab_id = id;
    g.buttons = 1;
    for (int i = 0; i < 3; ++i) {
      g.centre[i] = centre[i];
      g.force[i] = force[i];
    }
    g.radius = radius;
    return g;
  }
  void SendGrab(grab g) {
    g.utime = bus::NowUtime();
    grab_publisher_.Publish(g);
  }

  Eigen::Vector3d Position(int p) const { return received_.positions.row(p).transpose(); }
  double BottomHeight() const {
    double sum = 0.0;
    for (int j = 0; j < 17; ++j) sum += received_.positions(16 * 17 + j, 1);
    return sum / 17;
  }

  /// In mode B, pulls the bottom middle down with 1/4 N for 1.5 s as a device would (the
  /// sphere follows the grabbed point, read from the published frames).
  void PullDown(std::int64_t id) {
    for (int f = 0; f < 90; ++f) {
      SendGrab(MakeGrab(id, Position(kBottomMiddle), 0.3, Eigen::Vector3d(0, -0.25, 0)));
      Step();
    }
  }

  bus::LcmBus bus_;
  Received received_;
  bus::Publisher<grab> grab_publisher_{bus_, bus::kGrabChannel};
  bus::Publisher<command> command_publisher_{bus_, bus::kCommandChannel};
  std::unique_ptr<SimServer> server_;
};

TEST_F(SimServerTest, PublishesEveryFrameWithTheFrameNumber) {
  Step(3);
  EXPECT_EQ(received_.frame, 3);
  EXPECT_EQ(received_.positions.rows(), 17 * 17);
  EXPECT_EQ(received_.mode, costume_lcm::cloth_frame::MODE_ANIMATION);
  EXPECT_EQ(received_.num_patch_chunks, 0);  // no grab, no patch
}

TEST_F(SimServerTest, HapticPatchHoldsTheParticlesInTheSphereAndTheSpringsTouchingThem) {
  SendMode(command::MODE_EDITING);
  Step(30);
  const Eigen::Vector3d centre = Position(kBottomMiddle) + Eigen::Vector3d(0.01, 0, 0);
  const double radius = 0.2;
  // Oracle: brute force over the last published frame, which is the state the grab selects
  // from. Particles within float rounding of the sphere would be ambiguous: there are none.
  std::set<int> inside;
  for (int p = 0; p < received_.positions.rows(); ++p) {
    const double d = (Position(p) - centre).norm();
    ASSERT_GT(std::abs(d - radius), 1e-5) << "particle " << p << " on the sphere";
    if (d < radius) inside.insert(p);
  }
  ASSERT_GT(inside.size(), 5u);
  SendGrab(MakeGrab(0, centre, radius, Eigen::Vector3d::Zero()));
  Step();
  ASSERT_FALSE(received_.patch.empty());
  ASSERT_EQ(received_.patch.size(), 1u);  // 289 particles fit one chunk
  const costume_lcm::haptic_patch& patch = received_.patch[0];
  EXPECT_EQ(patch.frame, received_.frame);
  EXPECT_EQ(patch.grab_id, 0);
  EXPECT_EQ(patch.num_chunks, 1);
  std::set<int> selected;
  for (int i = 0; i < patch.num_particles; ++i) {
    if (patch.selected[i]) selected.insert(patch.particle_index[i]);
    // Positions are those of the frame this patch belongs to.
    EXPECT_EQ(patch.x[i], static_cast<float>(received_.positions(patch.particle_index[i], 0)));
    EXPECT_EQ(patch.weight[i] > 0, static_cast<bool>(patch.selected[i]));
  }
  EXPECT_EQ(selected, inside);
  // Springs: exactly the model's springs with an end among the selected particles.
  using Key = std::tuple<int, int, float, float, float>;
  std::multiset<Key> expected, got;
  for (const sim::Spring& s : server_->simulation().model().springs()) {
    if (!inside.count(s.a) && !inside.count(s.b)) continue;
    expected.insert({s.a, s.b, static_cast<float>(s.stiffness), static_cast<float>(s.damping),
                     static_cast<float>(s.rest_length)});
  }
  for (int k = 0; k < patch.num_springs; ++k) {
    got.insert({patch.particle_index[patch.spring_a[k]], patch.particle_index[patch.spring_b[k]],
                patch.stiffness[k], patch.damping[k], patch.rest_length[k]});
  }
  EXPECT_EQ(got, expected);
  EXPECT_EQ(patch.total_springs, static_cast<int>(expected.size()));
  // Every particle of the patch is selected or the other end of one of those springs.
  std::set<int> ends(inside);
  for (const Key& k : expected) ends.insert({std::get<0>(k), std::get<1>(k)});
  std::set<int> listed(patch.particle_index.begin(), patch.particle_index.end());
  EXPECT_EQ(listed, ends);
}

TEST_F(SimServerTest, AGrabPullingDownMovesTheGrabbedParticlesDown) {
  SendMode(command::MODE_EDITING);
  Step(kSettleFrames);
  const double rest = Position(kBottomMiddle).y();
  PullDown(0);
  EXPECT_LT(Position(kBottomMiddle).y(), rest - 0.05);
  EXPECT_GT(received_.num_patch_chunks, 80);
}

// Edit cases 1 and 2 of DESIGN.md through the server, then UNDO and REDO.
TEST_F(SimServerTest, EliminatingStretchKeepsTheClothWhereLeftAndUndoBringsItBack) {
  SendMode(command::MODE_EDITING);
  Step(kSettleFrames);
  const double rest = BottomHeight();
  const std::int64_t revision0 = received_.revision;

  // Case 1: pull, release (hover), settle: back near rest.
  PullDown(0);
  const double pulled = BottomHeight();
  grab hover = MakeGrab(0, Position(kBottomMiddle), 0.3, Eigen::Vector3d::Zero());
  hover.mode = grab::MODE_HOVER;
  SendGrab(hover);
  Step();
  EXPECT_EQ(server_->active_grab_id(), -1);
  Step(kSettleFrames);
  EXPECT_LT(pulled, rest - 0.05);
  EXPECT_NEAR(BottomHeight(), rest, 0.1 * (rest - pulled));

  // Case 2: pull, eliminate stretch over the whole sheet (as cloth_editing_test), release
  // by button: it stays near where it was left.
  PullDown(1);
  const double left_at = BottomHeight();
  command eliminate{};
  eliminate.kind = command::KIND_ELIMINATE_STRETCH;
  eliminate.grab_id = -1;
  eliminate.centre[1] = eliminate.centre[2] = -0.5;
  eliminate.radius = 2.0;
  SendCommand(eliminate);
  Step();
  EXPECT_EQ(received_.revision, revision0 + 1);
  grab up = MakeGrab(1, Position(kBottomMiddle), 0.3, Eigen::Vector3d::Zero());
  up.buttons = 0;
  SendGrab(up);
  Step(kSettleFrames);
  EXPECT_EQ(server_->active_grab_id(), -1);
  EXPECT_NEAR(BottomHeight(), left_at, 0.2 * (rest - left_at));

  // Undo: the original rest lengths, so it returns to rest.
  SendKind(command::KIND_UNDO);
  Step(kSettleFrames);
  EXPECT_EQ(received_.revision, revision0 + 2);
  EXPECT_NEAR(BottomHeight(), rest, 0.1 * (rest - left_at));
  server_->PublishStatus();
  Step();
  ASSERT_FALSE(received_.statuses.empty());
  EXPECT_EQ(received_.statuses.back().undo_depth, 0);
  EXPECT_EQ(received_.statuses.back().redo_depth, 1);
  EXPECT_EQ(received_.statuses.back().model_revision, revision0 + 2);

  // Redo re-applies the sphere edit; a second undo has nothing to take back after one more.
  SendKind(command::KIND_REDO);
  Step();
  EXPECT_EQ(received_.revision, revision0 + 3);
  EXPECT_EQ(server_->simulation().num_undoable_edits(), 1);
  EXPECT_EQ(server_->redo_depth(), 0);
}

TEST_F(SimServerTest, MalformedStaleAndOutOfOrderGrabsAreCountedAndIgnored) {
  SendMode(command::MODE_EDITING);
  Step(10);
  const Eigen::Vector3d centre = Position(kBottomMiddle);
  // Malformed: bytes that are no grab.
  const std::vector<std::uint8_t> junk = {1, 2, 3, 4, 5};
  bus_.Publish(bus::kGrabChannel, junk);
  // Stale: stamped 5 s ago.
  grab old = MakeGrab(0, centre, 0.2, Eigen::Vector3d::Zero());
  old.utime = bus::NowUtime() - 5'000'000;
  old.seq = 10;
  bus::Publish(bus_, bus::kGrabChannel, old);
  Step();
  EXPECT_EQ(server_->active_grab_id(), -1);
  // In order (seq 20), then out of order (seq 15, a different grab id): only the first acts.
  grab good = MakeGrab(3, centre, 0.2, Eigen::Vector3d::Zero());
  good.utime = bus::NowUtime();
  good.seq = 20;
  bus::Publish(bus_, bus::kGrabChannel, good);
  grab late = MakeGrab(4, centre, 0.2, Eigen::Vector3d::Zero());
  late.utime = good.utime;  // not newer: a late message, not a restarted sender
  late.seq = 15;
  bus::Publish(bus_, bus::kGrabChannel, late);
  // Invalid fields (negative radius), in order: decoded but refused.
  Step();
  EXPECT_EQ(server_->active_grab_id(), 3);
  grab bad = MakeGrab(3, centre, -1.0, Eigen::Vector3d::Zero());
  bad.utime = bus::NowUtime();
  bad.seq = 21;
  bus::Publish(bus_, bus::kGrabChannel, bad);
  // A stale grab id (an earlier press) arriving in seq order.
  grab earlier = MakeGrab(2, centre, 0.2, Eigen::Vector3d::Zero());
  earlier.utime = bus::NowUtime();
  earlier.seq = 22;
  Step();
  bus::Publish(bus_, bus::kGrabChannel, earlier);
  Step();
  EXPECT_EQ(server_->active_grab_id(), 3);
  EXPECT_EQ(server_->ignored().grabs_invalid, 1);
  EXPECT_EQ(server_->ignored().grabs_stale_id, 1);
  server_->PublishStatus();
  Step();
  ASSERT_FALSE(received_.statuses.empty());
  const costume_lcm::status& status = received_.statuses.back();
  EXPECT_EQ(status.dropped_malformed, 1);
  EXPECT_EQ(status.dropped_stale, 1);
  EXPECT_EQ(status.dropped_out_of_order, 1);
  EXPECT_EQ(status.mode, costume_lcm::status::MODE_EDITING);
}

TEST_F(SimServerTest, PauseStopsFramesAndStopReturnsToFrameZero) {
  Step(5);
  SendKind(command::KIND_PAUSE);
  Step();
  const std::int64_t paused_at = received_.frame;
  const sim::Points positions = received_.positions;
  Step(5);
  EXPECT_EQ(received_.frame, paused_at);
  EXPECT_EQ(received_.positions, positions);
  EXPECT_EQ(server_->playback(), Playback::kPaused);
  SendKind(command::KIND_PLAY);
  Step(2);
  EXPECT_EQ(received_.frame, paused_at + 2);
  SendKind(command::KIND_STOP);
  Step(3);
  EXPECT_EQ(received_.frame, 0);
  // Back at the scene's start: the rest positions.
  const sim::Points& rest = server_->simulation().model().rest_positions();
  EXPECT_LT((received_.positions - rest).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_EQ(server_->playback(), Playback::kStopped);
}

TEST_F(SimServerTest, AnimationModeIgnoresGrabs) {
  Step(5);
  SendGrab(MakeGrab(0, Position(kBottomMiddle), 0.3, Eigen::Vector3d(0, -1, 0)));
  Step(3);
  EXPECT_EQ(server_->active_grab_id(), -1);
  EXPECT_EQ(server_->ignored().grabs_in_animation, 1);
  EXPECT_EQ(received_.num_patch_chunks, 0);
  // Switching to mode A during a grab lets go.
  SendMode(command::MODE_EDITING);
  SendGrab(MakeGrab(1, Position(kBottomMiddle), 0.3, Eigen::Vector3d(0, -1, 0)));
  Step();
  EXPECT_EQ(server_->active_grab_id(), 1);
  SendMode(command::MODE_ANIMATION);
  Step();
  EXPECT_EQ(server_->active_grab_id(), -1);
}

TEST_F(SimServerTest, UnavailableCommandsWarnInStatusWithoutCrashing) {
  SendKind(command::KIND_LOAD_AVATAR);
  command solver{};
  solver.kind = command::KIND_SET_SOLVER;
  solver.solver.method = 77;
  SendCommand(solver);
  SendKind(99);
  Step();  // warnings make the status go out at the end of the Step
  Step();
  ASSERT_FALSE(received_.statuses.empty());
  const costume_lcm::status& status = received_.statuses.back();
  ASSERT_EQ(status.num_warnings, 3);
  EXPECT_NE(status.warnings[0].find("started without a catalogue"),
            std::string::npos);
  EXPECT_NE(status.warnings[1].find("solver.method = 77"), std::string::npos);
  EXPECT_EQ(server_->ignored().commands_refused, 3);
  EXPECT_EQ(received_.frame, 2);
}

// A solve stopped by its iteration cap before the tolerance is reported once per status, with
// the settings to change; a healthy solver says nothing.
TEST_F(SimServerTest, SolvesStoppedByTheIterationCapAreReportedOncePerStatus) {
  Step(70);  // the default solver converges: statuses without solver warnings
  for (const costume_lcm::status& status : received_.statuses) {
    for (const std::string& w : status.warnings) EXPECT_EQ(w.find("solver:"), std::string::npos) << w;
  }
  command solver{};
  solver.kind = command::KIND_SET_SOLVER;
  solver.solver.method = costume_lcm::solver_parameters::METHOD_PCG;
  solver.solver.tolerance = 1e-9;
  solver.solver.max_iterations = 1;
  solver.solver.substeps = 1;
  solver.solver.strain_limit = 0.1;
  SendCommand(solver);
  received_.statuses.clear();
  Step(60);
  ASSERT_FALSE(received_.statuses.empty());
  int reports = 0;
  for (const costume_lcm::status& status : received_.statuses) {
    for (const std::string& w : status.warnings) {
      if (w.find("solver:") == std::string::npos) continue;
      ++reports;
      EXPECT_NE(w.find("stopped at the iteration cap (max_iterations = 1)"), std::string::npos) << w;
      EXPECT_NE(w.find("tolerance (1e-09)"), std::string::npos) << w;
    }
  }
  EXPECT_EQ(reports, 1);  // one status period, one report
}

// A refused real-time priority (the grab acknowledger's) is repeated in every status, first,
// without making the server publish status every frame.
TEST_F(SimServerTest, AStandingWarningIsInEveryStatusWithoutForcingOne) {
  server_->SetStandingWarning("grab acknowledger: SCHED_FIFO priority 70 refused");
  Step(130);  // status at ticks 60 and 120 (status_period 1 s at 60 Hz)
  ASSERT_EQ(received_.statuses.size(), 2u);
  for (const costume_lcm::status& status : received_.statuses) {
    ASSERT_EQ(status.num_warnings, 1);
    EXPECT_EQ(status.warnings[0], "grab acknowledger: SCHED_FIFO priority 70 refused");
  }
}

TEST_F(SimServerTest, SetSolverChangesTheSolverInPlace) {
  Step(5);
  command solver{};
  solver.kind = command::KIND_SET_SOLVER;
  solver.solver.method = costume_lcm::solver_parameters::METHOD_DIRECT;
  solver.solver.tolerance = 1e-3;
  solver.solver.max_iterations = 100;
  solver.solver.substeps = 2;
  SendCommand(solver);
  Step();
  EXPECT_EQ(server_->simulation().scene().solver.method, sim::SolverMethod::kDirect);
  EXPECT_EQ(server_->simulation().scene().solver.substeps, 2);
  EXPECT_EQ(server_->scene().solver.method, sim::SolverMethod::kDirect);
  EXPECT_EQ(received_.frame, 6);  // no rebuild: the frames carry on
  EXPECT_TRUE(server_->pending_warnings().empty());
}

// After a stretch elimination: SET_SOLVER (direct, then hierarchical) keeps the positions
// bit for bit at the switch, the edited rest lengths and the undo history; an undo after the
// switch still restores the scene's rest lengths (the hierarchical pyramid rebuilt around
// them). Oracle: the model as Simulation::Build makes it, and the positions before the switch.
TEST_F(SimServerTest, SetSolverKeepsTheClothStateTheEditsAndTheUndoHistory) {
  SendMode(command::MODE_EDITING);
  Step(60);
  PullDown(0);
  command eliminate{};
  eliminate.kind = command::KIND_ELIMINATE_STRETCH;
  eliminate.grab_id = -1;
  eliminate.centre[1] = eliminate.centre[2] = -0.5;
  eliminate.radius = 2.0;
  SendCommand(eliminate);
  SendKind(command::KIND_PAUSE);
  Step();
  ASSERT_EQ(server_->simulation().num_undoable_edits(), 1);
  const std::shared_ptr<const sim::ClothModel> built_model =
      sim::Simulation::Build(SoftHang())->shared_model();
  const sim::ClothModel& built = *built_model;
  std::vector<double> edited;
  int num_edited = 0;
  for (int k = 0; k < server_->simulation().model().num_springs(); ++k) {
    edited.push_back(server_->simulation().model().springs()[k].rest_length);
    num_edited += edited.back() != built.springs()[k].rest_length;
  }
  ASSERT_GT(num_edited, 0);
  const sim::Points positions = server_->simulation().state().positions;
  const sim::Points velocities = server_->simulation().state().velocities;
  const double time = server_->simulation().state().time;
  const double avatar_time = server_->simulation().avatar_time();
  const std::int64_t frame = received_.frame;
  const std::int64_t revision = received_.revision;

  command solver{};
  solver.kind = command::KIND_SET_SOLVER;
  solver.solver.method = costume_lcm::solver_parameters::METHOD_DIRECT;
  solver.solver.tolerance = 1e-4;
  solver.solver.max_iterations = 100;
  solver.solver.substeps = 1;
  SendCommand(solver);
  Step();  // paused: the switch alone
  const sim::Simulation& sim = server_->simulation();
  EXPECT_EQ(sim.scene().solver.method, sim::SolverMethod::kDirect);
  EXPECT_EQ(sim.state().positions, positions);  // bit for bit
  EXPECT_EQ(sim.state().velocities, velocities);
  EXPECT_EQ(sim.state().time, time);
  EXPECT_EQ(sim.avatar_time(), avatar_time);
  EXPECT_EQ(received_.frame, frame);
  EXPECT_EQ(received_.revision, revision);
  for (int k = 0; k < sim.model().num_springs(); ++k) {
    ASSERT_EQ(sim.model().springs()[k].rest_length, edited[k]) << "spring " << k;
  }
  EXPECT_EQ(sim.num_undoable_edits(), 1);

  // The direct solver steps the edited cloth on.
  SendKind(command::KIND_PLAY);
  Step(30);
  EXPECT_EQ(received_.frame, frame + 30);
  EXPECT_TRUE(server_->simulation().state().positions.allFinite());
  EXPECT_GT((server_->simulation().state().positions - positions).cwiseAbs().maxCoeff(), 0.0);

  // Hierarchical, then undo: the scene's rest lengths come back; the cloth keeps stepping.
  solver.solver.method = costume_lcm::solver_parameters::METHOD_HIERARCHICAL;
  solver.solver.tolerance = 1e-3;
  SendCommand(solver);
  Step();
  EXPECT_EQ(server_->simulation().scene().solver.method, sim::SolverMethod::kHierarchical);
  SendKind(command::KIND_UNDO);
  Step();
  for (int k = 0; k < server_->simulation().model().num_springs(); ++k) {
    ASSERT_EQ(server_->simulation().model().springs()[k].rest_length,
              built.springs()[k].rest_length) << "spring " << k;
  }
  EXPECT_EQ(server_->simulation().num_undoable_edits(), 0);
  Step(30);
  EXPECT_TRUE(server_->simulation().state().positions.allFinite());

  // Multigrid with Galerkin coarse levels: the coarse operator reaches the scene.
  solver.solver.method = costume_lcm::solver_parameters::METHOD_MULTIGRID;
  solver.solver.coarse_operator = costume_lcm::solver_parameters::COARSE_GALERKIN;
  SendCommand(solver);
  Step(10);
  EXPECT_EQ(server_->simulation().scene().solver.method, sim::SolverMethod::kMultigrid);
  EXPECT_EQ(server_->simulation().scene().solver.coarse_operator, sim::CoarseOperator::kGalerkin);
  EXPECT_TRUE(server_->simulation().state().positions.allFinite());
  EXPECT_EQ(server_->ignored().commands_refused, 0);
}

// ELIMINATE_STRETCH naming the held grab uses that grab's sphere: the command's own sphere
// (radius 0) would be refused.
TEST_F(SimServerTest, EliminateStretchNamingTheHeldGrabUsesItsSphere) {
  SendMode(command::MODE_EDITING);
  Step(30);
  const std::int64_t revision0 = received_.revision;
  PullDown(7);
  command eliminate{};
  eliminate.kind = command::KIND_ELIMINATE_STRETCH;
  eliminate.grab_id = 7;
  SendCommand(eliminate);
  SendGrab(MakeGrab(7, Position(kBottomMiddle), 0.3, Eigen::Vector3d(0, -0.25, 0)));
  Step();
  EXPECT_EQ(received_.revision, revision0 + 1);
  EXPECT_EQ(server_->simulation().num_undoable_edits(), 1);
  // Only springs with both ends within 0.3 m of the sphere's centre changed.
  const std::shared_ptr<const sim::ClothModel> built_model =
      sim::Simulation::Build(SoftHang())->shared_model();
  const sim::ClothModel& built = *built_model;
  const sim::ClothModel& now = server_->simulation().model();
  int changed = 0;
  for (int k = 0; k < now.num_springs(); ++k) {
    if (now.springs()[k].rest_length != built.springs()[k].rest_length) ++changed;
  }
  EXPECT_GT(changed, 0);
  EXPECT_LT(changed, now.num_springs() / 2);
  // Naming no grab with no sphere is refused and counted.
  eliminate.grab_id = -1;
  SendCommand(eliminate);
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 1);
  EXPECT_EQ(received_.revision, revision0 + 1);
}

TEST_F(SimServerTest, AGrabWhoseMessagesStopIsReleased) {
  SendMode(command::MODE_EDITING);
  Step();
  SendGrab(MakeGrab(0, Position(kBottomMiddle), 0.3, Eigen::Vector3d::Zero()));
  Step();
  EXPECT_EQ(server_->active_grab_id(), 0);
  Step(15);  // 0.25 s at 60 Hz
  EXPECT_EQ(server_->active_grab_id(), 0);
  Step();
  EXPECT_EQ(server_->active_grab_id(), -1);
  EXPECT_EQ(server_->ignored().grabs_timed_out, 1);
}

}  // namespace
}  // namespace costume::sim_app

namespace costume::sim_app {
namespace {

// The real clock: six frames at 60 Hz span five periods (the first runs at once), and the
// hang scene's frames are far shorter than a period, so none overruns on an idle machine.
TEST(SimServerRun, StepsAtTheFrameRate) {
  bus::LcmBus bus("memq://");
  const SimServerOptions options;
  SimServer server(bus, SoftHang(), options);
  std::atomic<bool> stop{false};
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(server.Run(stop, 6), 6);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(elapsed, 5.0 / 60.0);
  EXPECT_EQ(server.frame(), 6);
  EXPECT_EQ(server.ticks(), 6);
  std::printf("6 frames in %.1f ms, %lld overruns\n", 1e3 * elapsed,
              static_cast<long long>(server.overruns()));
}

}  // namespace
}  // namespace costume::sim_app

namespace costume::sim_app {
namespace {

// Run on a scripted clock: every wake-up on time except the 60th, 40 ms late. By hand, with
// P = 16,666,667 ns: that frame's period is P + 40 ms; NextDeadline then skips two deadlines
// (missed = 2) and the next wake is 3P after the late frame's deadline, a period of
// 3P − 40 ms; the other 118 of the 120 periods are P.
TEST(SimServerRun, StatusCarriesTheFramePeriodFiguresOfAScriptedLoop) {
  bus::LcmBus bus("memq://");
  std::vector<costume_lcm::status> statuses;
  bus::Subscribe<costume_lcm::status>(bus, bus::kSimStatusChannel,
                                      [&](const costume_lcm::status& m) { statuses.push_back(m); });
  std::int64_t now = 5'000'000'000;
  int sleeps = 0;
  SimServerOptions options;
  options.status_period = 1e6;  // status only when the test asks
  options.clock_now = [&] { return now; };
  options.clock_sleep_until = [&](std::int64_t deadline) {
    now = std::max(now, deadline) + (++sleeps == 60 ? 40'000'000 : 0);
  };
  SimServer server(bus, SoftHang(), options);
  std::atomic<bool> stop{false};
  ASSERT_EQ(server.Run(stop, 121), 121);
  server.PublishStatus();
  bus.HandleSubscriptions(0);
  ASSERT_EQ(statuses.size(), 1u);
  const costume_lcm::status& s = statuses[0];
  const double period_us = 16'666.667;
  EXPECT_NEAR(s.period_p50_us, period_us, 1e-6);
  EXPECT_NEAR(s.period_p99_us, period_us, 1e-6);  // rank 119 of 120: still P
  EXPECT_NEAR(s.period_p999_us, period_us + 40'000.0, 1e-6);  // rank 120: the late one
  EXPECT_NEAR(s.period_max_us, period_us + 40'000.0, 1e-6);
  EXPECT_EQ(s.missed_ticks, 2);
  EXPECT_EQ(s.overruns, 2);
  // The next status covers only the frames after the first: 10 on-time periods.
  ASSERT_EQ(server.Run(stop, 11), 11);
  server.PublishStatus();
  bus.HandleSubscriptions(0);
  ASSERT_EQ(statuses.size(), 2u);
  EXPECT_NEAR(statuses[1].period_max_us, period_us, 1e-6);
  EXPECT_NEAR(statuses[1].period_p50_us, period_us, 1e-6);
  EXPECT_EQ(statuses[1].missed_ticks, 2);
}

TEST(ComputePeriodFigures, NearestRanksOfAKnownSet) {
  std::vector<std::int64_t> periods;
  for (int i = 1000; i >= 1; --i) periods.push_back(1000 * i);  // 1 .. 1000 µs, descending
  const PeriodFigures f = ComputePeriodFigures(periods);
  EXPECT_DOUBLE_EQ(f.p50_us, 500.0);
  EXPECT_DOUBLE_EQ(f.p99_us, 990.0);
  EXPECT_DOUBLE_EQ(f.p999_us, 999.0);
  EXPECT_DOUBLE_EQ(f.max_us, 1000.0);
  std::vector<std::int64_t> none;
  EXPECT_EQ(ComputePeriodFigures(none).max_us, 0.0);
}

}  // namespace
}  // namespace costume::sim_app

namespace costume::sim_app {
namespace {

/// The built-in garment scene (skirt on the walking avatar), driven in mode B so the avatar's
/// clock is frozen: the body moves only when its posture changes.
class PostureTest : public SimServerTest {
 protected:
  PostureTest() : SimServerTest(assets::LoadBuiltInScene("garment")) {}

  static command Posture(const std::vector<std::string>& names,
                         const std::vector<Eigen::Vector3d>& angles, double heading) {
    command c{};
    c.kind = command::KIND_SET_POSTURE;
    c.num_joints = static_cast<std::int16_t>(names.size());
    c.joint_names = names;
    c.joint_angles.assign(angles.size(), std::vector<double>(3, 0.0));
    for (std::size_t i = 0; i < angles.size(); ++i) {
      for (int k = 0; k < 3; ++k) c.joint_angles[i][k] = angles[i][k];
    }
    c.heading_degrees = heading;
    return c;
  }
};

// Oracle: the posture's placement turns the whole avatar about the world origin, applied last
// (pose.h), and the skirt's attached particles ride on their joints, so once the transition
// is over each attached particle sits at R_y(30°) times where it was; the arm's rotation is
// the scene file's convention (x, y, z about the rest axes, in that order) built here by hand.
TEST_F(PostureTest, SetPostureTurnsTheAvatarAndTheClothFollowsWithoutLosingItsState) {
  Step(20);  // past the fitting's reach time (0.25 s), before the walk (0.5 s): the posture
  SendMode(command::MODE_EDITING);  // the avatar's clock stops here
  Step();
  const std::int64_t frame = received_.frame;
  const std::int64_t revision = received_.revision;
  const sim::Points before = server_->simulation().state().positions;
  const sim::Points published = received_.positions;
  SendCommand(Posture({"l_shoulder"}, {Eigen::Vector3d(0, 0, -60)}, 30.0));
  Step();
  EXPECT_TRUE(server_->pending_warnings().empty());
  EXPECT_EQ(received_.frame, frame + 1);  // no rebuild: the frames carry on
  EXPECT_EQ(received_.revision, revision);
  EXPECT_LT((received_.positions - published).cwiseAbs().maxCoeff(), 0.02);  // one step's motion
  Step(40);  // the 0.5 s transition is over
  const sim::AvatarMotion& avatar = *server_->simulation().avatar();
  const double degree = std::acos(-1.0) / 180.0;
  const Eigen::Quaterniond heading(Eigen::AngleAxisd(30 * degree, Eigen::Vector3d::UnitY()));
  EXPECT_LT(avatar.pose().orientation.angularDistance(heading), 1e-9);
  const int shoulder = avatar.avatar().skeleton().Find(sim::HAnimJoint::kLShoulder);
  ASSERT_GE(shoulder, 0);
  const Eigen::Quaterniond arm(Eigen::AngleAxisd(-60 * degree, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(avatar.pose().rotations[shoulder].angularDistance(arm), 1e-9);
  const Eigen::Matrix3d turn = heading.toRotationMatrix();
  const auto& attachments = server_->simulation().attachments();
  ASSERT_FALSE(attachments.empty());
  const sim::Points& now = server_->simulation().state().positions;
  double worst = 0.0;
  for (const sim::BodyAttachment& a : attachments) {
    const Eigen::Vector3d expected = turn * before.row(a.particle).transpose();
    worst = std::max(worst, (now.row(a.particle).transpose() - expected).norm());
  }
  EXPECT_LT(worst, 1e-9);
  // The free cloth turned with the body. Gravity is along −y, so turning everything about +y
  // is a symmetry: a reference run without the command, turned by R, is where the cloth
  // should be, up to what friction twists into the skirt during the 0.5 s turn (measured:
  // 4.2 cm on average, against 9.8 cm from the unturned reference; the same 1.5 s later).
  // It must be clearly nearer to the turned reference. How much nearer moves with rounding:
  // the same run with the solver's dot products summed in chunks of 128, 256 or 512
  // particles gave ratios 0.35, 0.51 and 0.40 (the skirt settles into a slightly different
  // fold), so the bound is 0.6; a cloth left behind by the turn gives about 1 or more.
  auto reference = sim::Simulation::Build(assets::LoadBuiltInScene("garment"));
  for (int f = 0; f < 20; ++f) reference->AdvanceFrame();
  reference->SetAvatarFrozen(true);
  while (reference->state().time < server_->simulation().state().time - 1e-9) {
    reference->AdvanceFrame();
  }
  const sim::Points& x_ref = reference->state().positions;
  double to_turned = 0.0, to_unturned = 0.0;
  for (int p = 0; p < now.rows(); ++p) {
    const Eigen::Vector3d turned = turn * x_ref.row(p).transpose();
    to_turned += (now.row(p).transpose() - turned).norm();
    to_unturned += (now.row(p) - x_ref.row(p)).norm();
  }
  std::printf("mean distance to the turned reference %.4f m, to the unturned %.4f m\n",
              to_turned / now.rows(), to_unturned / now.rows());
  EXPECT_LT(to_turned, 0.6 * to_unturned);
  EXPECT_EQ(server_->scene().avatar->motion.posture.rotations[shoulder].coeffs(), arm.coeffs());
}

TEST_F(PostureTest, UnknownJointsAndAnglesBeyondATurnAreRefusedNamingTheField) {
  SendMode(command::MODE_EDITING);
  Step(5);
  const Eigen::Quaterniond before = server_->simulation().avatar()->pose().orientation;
  SendCommand(Posture({"l_wing"}, {Eigen::Vector3d(0, 0, 10)}, 0.0));
  SendCommand(Posture({"l_shoulder", "r_elbow"},
                      {Eigen::Vector3d(0, 0, 10), Eigen::Vector3d(std::nan(""), 0, 0)}, 0.0));
  SendCommand(Posture({}, {}, std::numeric_limits<double>::infinity()));
  SendCommand(Posture({"l_knee"}, {Eigen::Vector3d(0, 1e300, 0)}, 0.0));
  Step();
  Step();
  ASSERT_FALSE(received_.statuses.empty());
  const std::vector<std::string>& w = received_.statuses.back().warnings;
  ASSERT_EQ(w.size(), 4u);
  EXPECT_NE(w[0].find("joint_names[0] = 'l_wing'"), std::string::npos) << w[0];
  EXPECT_NE(w[1].find("joint_angles[1]"), std::string::npos) << w[1];
  EXPECT_NE(w[1].find("r_elbow"), std::string::npos) << w[1];
  EXPECT_NE(w[2].find("heading_degrees = inf"), std::string::npos) << w[2];
  EXPECT_NE(w[3].find("'l_knee': each must be finite, within [-360, 360]"), std::string::npos)
      << w[3];
  EXPECT_EQ(server_->ignored().commands_refused, 4);
  Step(35);
  EXPECT_EQ(server_->simulation().avatar()->pose().orientation.coeffs(), before.coeffs());
}

// SET_POSTURE's arms' spread (sim_core/scene/arm_spread.h): given angles become the
// avatar's, in place and for a STOP's rebuild; "auto" hands the choice back to the
// simulation (none for the built-in walk, which keeps its forearms off the body: FindArmSpread
// tests); a mode or an angle out of range is refused, naming the field, the spread unchanged.
TEST_F(PostureTest, SetPostureSetsTheArmsSpreadGivenOrChosenAndRefusesBadOnes) {
  Step(5);
  const double degree = std::acos(-1.0) / 180.0;
  command c = Posture({}, {}, 0.0);
  c.arm_spread_mode = command::ARM_SPREAD_GIVEN;
  c.arm_spread_degrees[0] = 12.0;
  c.arm_spread_degrees[1] = 6.0;
  SendCommand(c);
  Step();
  EXPECT_TRUE(server_->pending_warnings().empty());
  const auto spread = [&] { return server_->simulation().avatar()->settings().arm_spread; };
  EXPECT_NEAR(spread()[0], 12.0 * degree, 1e-12);
  EXPECT_NEAR(spread()[1], 6.0 * degree, 1e-12);
  EXPECT_FALSE(server_->scene().avatar->auto_arm_spread);
  SendCommand([] { command stop{}; stop.kind = command::KIND_STOP; return stop; }());
  Step();
  EXPECT_NEAR(spread()[0], 12.0 * degree, 1e-12);
  EXPECT_EQ(server_->simulation().arm_spread().why_not, "as given, not chosen");

  const std::array<double, 2> given = spread();
  received_.statuses.clear();
  c.arm_spread_mode = 5;
  SendCommand(c);
  c.arm_spread_mode = command::ARM_SPREAD_GIVEN;
  c.arm_spread_degrees[0] = 31.0;
  SendCommand(c);
  c.arm_spread_degrees[0] = 0.0;
  c.arm_spread_degrees[1] = std::nan("");
  SendCommand(c);
  Step();
  Step();
  ASSERT_FALSE(received_.statuses.empty());
  const std::vector<std::string>& w = received_.statuses.back().warnings;
  ASSERT_EQ(w.size(), 3u);
  EXPECT_NE(w[0].find("arm_spread_mode = 5: must be 0 (keep), 1 (auto) or 2 (given)"),
            std::string::npos) << w[0];
  EXPECT_NE(w[1].find("arm_spread_degrees[0] = 31.0"), std::string::npos) << w[1];
  EXPECT_NE(w[1].find("within [0, 30]"), std::string::npos) << w[1];
  EXPECT_NE(w[2].find("arm_spread_degrees[1] = nan"), std::string::npos) << w[2];
  EXPECT_EQ(server_->ignored().commands_refused, 3);
  EXPECT_EQ(spread(), given);

  c.arm_spread_mode = command::ARM_SPREAD_AUTO;
  SendCommand(c);
  Step();
  EXPECT_TRUE(server_->scene().avatar->auto_arm_spread);
  EXPECT_TRUE(server_->simulation().arm_spread().measured);
  EXPECT_EQ(spread(), (std::array<double, 2>{0.0, 0.0}));
}

// SET_COLLISION on the garment scene: the method changes in place (the frames carry on, the
// server's scene follows for a later rebuild); a thickness out of range is refused with a
// warning naming the field, and the collider stays.
TEST_F(PostureTest, SetCollisionChangesTheMethodInPlaceAndRefusesBadValues) {
  Step(5);
  const std::int64_t frame = received_.frame;
  command c{};
  c.kind = command::KIND_SET_COLLISION;
  c.collision = bus::ToMessage(sim::CollisionSettingsOf(server_->scene()));
  const bool was_mesh = server_->scene().avatar->collision == sim::BodyCollisionMethod::kMesh;
  const sim::BodyCollisionMethod wanted =
      was_mesh ? sim::BodyCollisionMethod::kSuperquadric : sim::BodyCollisionMethod::kMesh;
  c.collision.method = was_mesh ? costume_lcm::collision_parameters::METHOD_SUPERQUADRIC
                                : costume_lcm::collision_parameters::METHOD_MESH;
  c.collision.max_skin_travel = 0.03;
  SendCommand(c);
  Step();
  EXPECT_TRUE(server_->pending_warnings().empty());
  EXPECT_EQ(received_.frame, frame + 1);  // no rebuild
  EXPECT_EQ(server_->simulation().scene().avatar->collision, wanted);
  EXPECT_EQ(server_->scene().avatar->collision, wanted);
  EXPECT_EQ(server_->scene().avatar->max_skin_travel, 0.03);
  const sim::BodyCollider* collider = server_->simulation().body_collider();
  c.collision.thickness = 0.2;
  received_.statuses.clear();
  SendCommand(c);
  Step();  // the warning makes the status go out at the end of the Step
  Step();
  ASSERT_FALSE(received_.statuses.empty());
  const std::vector<std::string>& w = received_.statuses.back().warnings;
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("SET_COLLISION refused"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("avatar.thickness = 0.2"), std::string::npos) << w[0];
  EXPECT_EQ(server_->simulation().body_collider(), collider);
  EXPECT_EQ(server_->scene().avatar->thickness, 0.004);
  EXPECT_EQ(server_->ignored().commands_refused, 1);
  // A STOP rebuilds around the superquadric collider SET_COLLISION built (sim::ColliderMemo:
  // its fit and drawings are kept); a mesh one is built anew.
  SendKind(command::KIND_STOP);
  Step();
  EXPECT_EQ(received_.frame, 0);
  EXPECT_EQ(server_->simulation().body_collider() == collider,
            wanted == sim::BodyCollisionMethod::kSuperquadric);
}

TEST_F(SimServerTest, SetPostureWithoutAnAvatarIsRefused) {
  command c{};
  c.kind = command::KIND_SET_POSTURE;
  SendCommand(c);
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 1);
}

}  // namespace
}  // namespace costume::sim_app
