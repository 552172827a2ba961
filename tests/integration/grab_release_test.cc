// The three-process shape of issue 5, two of the processes for real: costume_sim_server (hang
// scene, editing mode) and costume_haptic_server (simulated device on a scripted trajectory)
// exchange grabs and haptic patches over UDP multicast LCM; this test listens to the cloth
// frames like the GUI would. Run only inside a private network namespace (ctest wraps it in
// `unshare -n` with a multicast route on lo, tests/CMakeLists.txt), so nothing leaves it.
//
// Edit case 1 (DESIGN.md): the device grabs the middle of the hanging sheet, pulls it 10 cm
// and lets go; the cloth follows the pull (through the simulation's implicit coupling,
// grab.coupling_stiffness) and then returns to rest.
#include <gtest/gtest.h>
#include <unistd.h>
#include <signal.h>
#include <sys/wait.h>

#include <Eigen/Core>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <thread>

#include <lcm/lcm-cpp.hpp>

#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/feedback.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"
#include "lcm_types/costume_lcm/status.hpp"
#include "tests/support/child_process.h"
#include "tests/support/network_namespace.h"
#include "tests/support/test_scenes.h"

namespace costume {
namespace {

using testing::InNetworkNamespace;
using testing::kNeedsNetworkNamespace;
using testing::Spawn;
using testing::Terminate;
using testing::Wait;
using test::HangingSheetScene;
using test::kStiffCottonCloth;

/// The LCM URL of the run: COSTUME_LCM_URL when the two-host setup sets it (ttl=1 over a veth
/// pair), else the default (ttl=0).
std::string LcmUrl() {
  const char* url = std::getenv("COSTUME_LCM_URL");
  return url ? url : "";
}

/// The processes' options for that URL: a URL that leaves the host must be allowed.
std::vector<std::string> UrlArgs(const char* allow_flag) {
  if (LcmUrl().empty()) return {};
  return {"--lcm-url", LcmUrl(), allow_flag};
}

/// The haptic server's command line, run in the other "host" (network namespace
/// COSTUME_HAPTIC_NETNS_PID) when the two-host setup asks for it.
std::vector<std::string> OnHapticHost(std::vector<std::string> argv) {
  const char* pid = std::getenv("COSTUME_HAPTIC_NETNS_PID");
  if (!pid) return argv;
  std::vector<std::string> wrapped = {"/usr/bin/nsenter", "-t", pid, "-n", "--"};
  wrapped.insert(wrapped.end(), argv.begin(), argv.end());
  return wrapped;
}

std::vector<std::string> Concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

/// The cloth's frames as they arrive: frame number → position of one watched particle, and
/// the seq of the last grab message the simulation had taken in when it made the frame
/// (cloth_frame.grab_seq), which ties each frame to what the device was doing.
struct FrameLog {
  int particle = 0;
  std::map<int64_t, Eigen::Vector3d> positions;
  std::map<int64_t, int64_t> grab_seq;
  void OnFrame(const costume_lcm::cloth_frame& frame) {
    grab_seq[frame.frame] = frame.grab_seq;
    const int i = particle - frame.first_particle;
    if (i < 0 || i >= frame.num_particles) return;
    positions[frame.frame] = Eigen::Vector3d(frame.x[i], frame.y[i], frame.z[i]);
  }
};

/// What the listener saw of one two-process run.
struct ProcessRun {
  std::map<int64_t, Eigen::Vector3d> positions;  // watched particle per frame [m]
  std::map<int64_t, int64_t> grab_seq;           // cloth_frame.grab_seq per frame
  int grabs = 0, patches = 0;
  std::set<int64_t> patch_frames;  // frames a haptic_patch chunk was published for
  double strongest = 0.0;  // largest F_h in a grab message [N]
  int undo_depth = 0;      // the simulation server's largest reported undo depth
  int sim_exit = -1, haptic_exit = -1;
  int64_t first_press_seq = -1;    // the first pressed grab message's seq
  int64_t first_release_seq = -1;  // the first unpressed one after it

  /// The watched particle at a time [s] (the first frame at or after it).
  Eigen::Vector3d At(double seconds) const { return AtFrame(static_cast<int64_t>(seconds * 60)); }
  /// The watched particle at frame `frame` (the first frame at or after it that arrived).
  Eigen::Vector3d AtFrame(int64_t frame) const {
    const auto found = positions.lower_bound(frame);
    return found == positions.end() ? positions.rbegin()->second : found->second;
  }
  /// The first frame the simulation made after taking in grab message `seq` (or a later
  /// one); −1 when none did. Frame numbers are simulated time (1/60 s each), whatever the
  /// wall-clock speed the loaded machine allowed.
  int64_t FrameAfterGrab(int64_t seq) const {
    if (seq < 0) return -1;
    for (const auto& [frame, taken] : grab_seq) {
      if (taken >= seq) return frame;
    }
    return -1;
  }
  int64_t PressFrame() const { return FrameAfterGrab(first_press_seq); }
  int64_t ReleaseFrame() const { return FrameAfterGrab(first_release_seq); }
};

/// How long a run lasts.
struct RunLength {
  /// The simulation server stops by itself after this many frames (--frames); 0: it runs
  /// until the release has been followed by `settle_frames` frames, then gets SIGTERM.
  int frames = 0;
  /// Frames to simulate after the frame that took in the release (frames == 0).
  int settle_frames = 0;
  /// The device's trajectory length (the haptic server's --seconds) [s].
  double device_seconds = 0.0;
  /// The haptic server (and its trajectory) starts once this frame has arrived (>= 1): the
  /// cloth settles for this much simulated time first, however slowly the machine runs.
  int frames_before_device = 1;
};

/// Writes `scene` and `trajectory` to a temporary folder, starts costume_sim_server (editing
/// mode) and, once its first cloth frame arrived, costume_haptic_server (simulated device at
/// `offset`, grab radius `radius`), and listens to the cloth frames, grabs and patches until
/// the run is over (`length`). Nothing waits on fixed wall-clock times: on a loaded machine
/// the 60 Hz loop skips deadlines and simulated time falls behind the device's wall-clock
/// trajectory, so the test locates the press and the release in simulated time through
/// cloth_frame.grab_seq and waits for the frames it needs (a generous time limit only guards
/// against a hang).
ProcessRun RunProcesses(const std::string& scene, const std::string& trajectory,
                        const RunLength& length, const std::vector<std::string>& offset,
                        const std::string& radius, int particle,
                        const std::filesystem::path& record = {},
                        const std::function<void(bus::LcmBus&, int)>& during = nullptr) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("costume_grab_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.toml") << scene;
  // lcm-logger records the session when asked (started first, so it sees every frame).
  const pid_t logger =
      record.empty() ? -1
                  : Spawn({"/usr/bin/lcm-logger", "--lcm-url=" + (LcmUrl().empty()
                                                                     ? std::string("udpm://239.255.76.67:7667?ttl=0")
                                                                     : LcmUrl()),
                           "-f", "--flush-interval=10", record.string()});
  if (logger > 0) std::this_thread::sleep_for(std::chrono::milliseconds(300));
  std::ofstream(dir / "pull.traj") << trajectory;
  bus::LcmBus listener(LcmUrl(), bus::Reach::kNetwork);
  FrameLog log;
  log.particle = particle;
  ProcessRun run;
  bus::Subscribe<costume_lcm::cloth_frame>(
      listener, bus::kClothFrameChannel,
      [&log](const costume_lcm::cloth_frame& frame) { log.OnFrame(frame); });
  bool pressed_seen = false;
  bus::Subscribe<costume_lcm::grab>(listener, bus::kGrabChannel, [&](const costume_lcm::grab& grab) {
    const bool pressed = grab.mode == costume_lcm::grab::MODE_GRAB && (grab.buttons & 1) != 0;
    if (pressed && run.first_press_seq < 0) run.first_press_seq = grab.seq;
    if (pressed) pressed_seen = true;
    if (!pressed && pressed_seen && run.first_release_seq < 0) run.first_release_seq = grab.seq;
    if (grab.mode != costume_lcm::grab::MODE_GRAB) return;
    ++run.grabs;
    run.strongest = std::max(run.strongest,
                             Eigen::Vector3d(grab.force[0], grab.force[1], grab.force[2]).norm());
  });
  bus::Subscribe<costume_lcm::haptic_patch>(
      listener, bus::kHapticPatchChannel, [&run](const costume_lcm::haptic_patch& p) {
        ++run.patches;
        run.patch_frames.insert(p.frame);
      });
  bus::Subscribe<costume_lcm::status>(listener, bus::kSimStatusChannel, [&run](const costume_lcm::status& s) {
    run.undo_depth = std::max(run.undo_depth, static_cast<int>(s.undo_depth));
  });

  const std::string root = COSTUME_BUILD_DIR;
  std::vector<std::string> sim_args = {root + "/sim_core/app/costume_sim_server", "--scene",
                                       (dir / "scene.toml").string(), "--editing"};
  if (length.frames > 0) sim_args = Concat(sim_args, {"--frames", std::to_string(length.frames)});
  const pid_t sim = Spawn(Concat(sim_args, UrlArgs("--allow-network")));
  // Only a server that is up can take the device's grabs, and the cloth settles for
  // frames_before_device frames: the trajectory starts after that.
  const auto started = std::chrono::steady_clock::now();
  const auto give_up =
      started + std::chrono::seconds(60 + static_cast<int>(
                                              10 * (length.device_seconds + length.frames / 60.0 +
                                                    (length.settle_frames +
                                                     length.frames_before_device) / 60.0)));
  while ((log.grab_seq.empty() || log.grab_seq.rbegin()->first < length.frames_before_device) &&
         std::chrono::steady_clock::now() < give_up) {
    listener.HandleSubscriptions(50);
  }
  const pid_t haptic = Spawn(OnHapticHost(Concat(
      {root + "/haptic_server/costume_haptic_server", "--device", "simulated", "--trajectory",
       (dir / "pull.traj").string(), "--offset", offset[0], offset[1], offset[2], "--radius",
       radius, "--seconds", std::to_string(length.device_seconds), "--priority", "0"},
      UrlArgs("--allow-network"))));
  bool haptic_done = false;
  while (std::chrono::steady_clock::now() < give_up) {
    listener.HandleSubscriptions(50);
    if (during) during(listener, static_cast<int>(log.positions.size()));
    int status = 0;
    if (!haptic_done && waitpid(haptic, &status, WNOHANG) == haptic) {
      haptic_done = true;
      run.haptic_exit = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    if (length.frames > 0) {
      if (haptic_done && static_cast<int>(log.positions.size()) >= length.frames) break;
      int sim_status = 0;
      if (haptic_done && waitpid(sim, &sim_status, WNOHANG) == sim) {  // done, frames lost
        run.sim_exit = WIFEXITED(sim_status) ? WEXITSTATUS(sim_status) : -1;
        break;
      }
      continue;
    }
    if (!haptic_done || log.grab_seq.empty()) continue;
    run.grab_seq = log.grab_seq;
    const int64_t release = run.ReleaseFrame();
    if (release < 0 && run.first_release_seq >= 0) continue;  // not taken in yet
    if (release < 0 || log.grab_seq.rbegin()->first >= release + length.settle_frames) break;
  }
  if (!haptic_done) run.haptic_exit = Wait(haptic);
  if (length.frames == 0) kill(sim, SIGTERM);
  if (run.sim_exit < 0) run.sim_exit = Wait(sim);
  if (logger > 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    kill(logger, SIGINT);
    Wait(logger);
  }
  run.positions = std::move(log.positions);
  run.grab_seq = std::move(log.grab_seq);
  std::filesystem::remove_all(dir);
  return run;
}


// Case 1 on stiff cotton (33 × 33): after 2 s of simulated time the device comes, rests 1 s
// at the sheet's middle, presses,
// pulls 10 cm along +z (out of the sheet) in 1 s, holds 2 s, releases; the simulation then
// runs 4 s more (simulated time: 240 frames after the one that took in the release).
TEST(GrabRelease, PulledClothFollowsTheDeviceAndReturnsToRestWhenReleased) {
  if (!InNetworkNamespace()) GTEST_SKIP() << kNeedsNetworkNamespace;
  const ProcessRun run = RunProcesses(
      HangingSheetScene(33, kStiffCottonCloth),
      "0.0 0 0 0 0\n1.0 0 0 0 0\n1.0 0 0 0 1\n2.0 0 0 0.10 1\n4.0 0 0 0.10 1\n"
      "4.0 0 0 0.10 0\n5.0 0 0 0.10 0\n",
      {.frames = 0, .settle_frames = 240, .device_seconds = 5.0, .frames_before_device = 120},
      {"0", "-0.5", "-0.5"}, "0.05", 16 * 33 + 16);
  EXPECT_EQ(run.haptic_exit, 0);
  EXPECT_EQ(run.sim_exit, 0);
  const int64_t press = run.PressFrame(), release = run.ReleaseFrame();
  ASSERT_GT(press, 1) << "the simulation never took in the press";
  ASSERT_GT(release, press) << "the simulation never took in the release";
  const Eigen::Vector3d rest = run.AtFrame(press - 1), pulled = run.AtFrame(release - 1),
                        released = run.AtFrame(release + 240);
  ASSERT_GE(run.positions.rbegin()->first, release + 240) << "cloth frames lost";
  std::printf("case 1, middle particle z: rest %.4f m (frame %lld), pulled %.4f m (frame %lld), "
              "4 s after release %.4f m; %d grab messages (strongest F_h %.3f N), %d patch "
              "chunks for %zu frames\n",
              rest.z(), static_cast<long long>(press - 1), pulled.z(),
              static_cast<long long>(release - 1), released.z(), run.grabs, run.strongest,
              run.patches, run.patch_frames.size());
  // The device held the button 3 s at 250 Hz (~750 grab messages; fewer when its loop skips
  // ticks under load); the simulation answered every frame it held the grab with a patch
  // (one chunk each for this small selection; a few may be lost on a loaded listener).
  EXPECT_GT(run.grabs, 150);
  int64_t answered = 0;
  for (int64_t f = press; f < release; ++f) answered += run.patch_frames.count(f);
  EXPECT_GE(answered, (release - press) * 9 / 10) << "of " << release - press << " frames";
  EXPECT_GT(pulled.z() - rest.z(), 0.08);                               // followed the 10 cm pull
  // and came back (the stiff sheet still swings a centimetre or so 4 s later)
  EXPECT_LT((released - rest).norm(), 0.2 * (pulled - rest).norm());
}

// Case 2 on a soft sheet (17 × 17, 20 N/m, so the pull stretches it): the sheet settles for 8 s
// of simulated time, then the device rests 1 s at the middle of the bottom edge, presses, pulls 10 cm down in 1 s, presses
// the stretch button (bit 1: KIND_ELIMINATE_STRETCH over the grab's sphere) while holding,
// releases 1 s later; the simulation then runs 6 s more (360 frames after the release frame).
// The pull stretches the whole height of the sheet, so the sphere (1.5 m) covers it all,
// pinned corners included; the stretched cloth then stays down instead of springing back.
TEST(GrabRelease, StretchMadePermanentWhileHeldStaysAfterRelease) {
  if (!InNetworkNamespace()) GTEST_SKIP() << kNeedsNetworkNamespace;
  const ProcessRun run = RunProcesses(
      HangingSheetScene(17, "[[material]]\nname = \"cloth\"\nstretch_stiffness = 20\n"
                       "shear_stiffness = 20\nbending_rigidity = 1e-6\n"),
      "0.0 0 0 0 0\n1.0 0 0 0 0\n1.0 0 0 0 1\n2.0 0 -0.10 0 1\n2.4 0 -0.10 0 1\n"
      "2.4 0 -0.10 0 3\n2.6 0 -0.10 0 3\n2.6 0 -0.10 0 1\n3.0 0 -0.10 0 1\n"
      "3.0 0 -0.10 0 0\n4.0 0 -0.10 0 0\n",
      {.frames = 0, .settle_frames = 360, .device_seconds = 4.0, .frames_before_device = 480},
      {"0", "-1.03", "-0.5"}, "1.5", 16 * 17 + 8);
  EXPECT_EQ(run.haptic_exit, 0);
  EXPECT_EQ(run.sim_exit, 0);
  const int64_t press = run.PressFrame(), release = run.ReleaseFrame();
  ASSERT_GT(press, 1) << "the simulation never took in the press";
  ASSERT_GT(release, press) << "the simulation never took in the release";
  ASSERT_GE(run.positions.rbegin()->first, release + 360) << "cloth frames lost";
  const Eigen::Vector3d rest = run.AtFrame(press - 1), pulled = run.AtFrame(release - 1),
                        after = run.AtFrame(release + 360);
  std::printf("case 2, bottom middle y: rest %.4f m (frame %lld), pulled %.4f m (frame %lld), "
              "6 s after release %.4f m; undo depth %d\n",
              rest.y(), static_cast<long long>(press - 1), pulled.y(),
              static_cast<long long>(release - 1), after.y(), run.undo_depth);
  EXPECT_EQ(run.undo_depth, 1);  // the stretch button reached the simulation once
  EXPECT_LT(pulled.y(), rest.y() - 0.05);                                  // stretched down
  // It stays down: the new rest lengths are the stretched ones, so only gravity's own sag on
  // the longer sheet (about the 4 cm it sagged at rest) moves it further; case 1 springs all
  // the way back.
  EXPECT_LT(after.y(), rest.y() - 0.5 * (rest.y() - pulled.y()));
  EXPECT_LT(std::abs(after.y() - pulled.y()), 0.5 * (rest.y() - pulled.y()));
}

/// Commands the live server must drop, sent once on COSTUME_COMMAND after `at_frame` cloth
/// frames: a STOP stamped 5 s ago, a STOP an hour ahead (both stale), a repeated and a
/// decreasing seq (both out of order; STOP again) around two PLAYs (accepted, and harmless
/// while playing), the last of which carries the channel's seq past all of them. Accepted, any
/// STOP would rebuild the simulation and the frames would differ.
struct DroppedCommands {
  int at_frame = 30;
  bool sent = false;
  void operator()(bus::LcmBus& bus, int frames) {
    if (sent || frames < at_frame) return;
    sent = true;
    auto send = [&bus](std::int8_t kind, std::int64_t utime, std::int64_t seq) {
      costume_lcm::command c{};
      c.kind = kind;
      c.utime = utime;
      c.seq = seq;
      EXPECT_TRUE(bus::Publish(bus, bus::kCommandChannel, c));
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    };
    using C = costume_lcm::command;
    send(C::KIND_STOP, bus::NowUtime() - 5'000'000, 0);
    send(C::KIND_STOP, bus::NowUtime() + 3'600'000'000LL, 1);
    const std::int64_t now = bus::NowUtime();
    send(C::KIND_PLAY, now, 2);
    send(C::KIND_STOP, now, 2);
    send(C::KIND_STOP, now, 1);
    send(C::KIND_PLAY, bus::NowUtime(), 3);
  }
};

// Record and replay (issue 5): lcm-logger records case 1; tools/replay feeds the logged grabs
// and commands to a fresh simulation server frame by frame and must reproduce every recorded
// cloth frame bit for bit — also with stale and out-of-order commands in the session, which the
// live server dropped and the replay must drop again, judged on the log's receive times.
TEST(GrabRelease, ReplayOfARecordedSessionReproducesItsClothFramesBitForBit) {
  if (!InNetworkNamespace()) GTEST_SKIP() << kNeedsNetworkNamespace;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("costume_replay_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string scene = HangingSheetScene(33, kStiffCottonCloth);
  std::ofstream(dir / "scene.toml") << scene;
  const ProcessRun run = RunProcesses(
      scene,
      "0.0 0 0 0 0\n1.0 0 0 0 0\n1.0 0 0 0 1\n2.0 0 0 0.10 1\n3.0 0 0 0.10 1\n"
      "3.0 0 0 0.10 0\n4.0 0 0 0.10 0\n",
      {.frames = 240, .settle_frames = 0, .device_seconds = 4.0, .frames_before_device = 1},
      {"0", "-0.5", "-0.5"}, "0.05", 16 * 33 + 16, dir / "session.lcm", DroppedCommands{});
  ASSERT_EQ(run.sim_exit, 0);
  ASSERT_GT(run.grabs, 100);
  // The live server dropped them: no STOP took it back to frame 0 (frames only increase).
  ASSERT_GE(run.positions.size(), 200u);
  EXPECT_EQ(run.positions.begin()->first, 1);
  EXPECT_EQ(run.positions.rbegin()->first, 240);
  const auto replay = [&dir](const std::string& log) {
    const std::string command = std::string(COSTUME_BUILD_DIR) + "/tools/replay " +
                                (dir / log).string() + " --scene " + (dir / "scene.toml").string();
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  const int whole = replay("session.lcm");
  // A log without grab seqs 400-499 (sent while the device holds the cloth) lacks inputs
  // the frames name: the replay must say so (exit 3), not only that the frames differ.
  {
    lcm::LogFile in((dir / "session.lcm").string(), "r");
    lcm::LogFile out((dir / "cut.lcm").string(), "w");
    ASSERT_TRUE(in.good() && out.good());
    while (const lcm::LogEvent* event = in.readNextEvent()) {
      costume_lcm::grab grab;
      if (event->channel == bus::kGrabChannel &&
          grab.decode(event->data, 0, event->datalen) == event->datalen && grab.seq >= 400 &&
          grab.seq < 500) {
        continue;
      }
      lcm::LogEvent copy = *event;
      out.writeEvent(&copy);
    }
  }
  const int cut = replay("cut.lcm");
  std::filesystem::remove_all(dir);
  EXPECT_EQ(cut, 3) << "a log missing grabs the live server took in";
  // The same on the whole log means lcm-logger, a normal-priority process with its own
  // socket, missed a message the server took in: the replay cannot be judged then. (Once, on
  // an AddressSanitizer build with another test beside this one, the frames differed from
  // frame 31; that log was not kept.)
  if (whole == 3) GTEST_SKIP() << "lcm-logger missed an input under load: replay not judged";
  EXPECT_EQ(whole, 0);
}

// The safety case of issue 5: `kill -9` of the simulation server while the device holds a
// stretched grab. The haptic server sees no more patches and must bring the device force to
// zero within 50 ms of the last patch; it keeps running, and once a new simulation server is
// up it grabs again and renders force again.
TEST(GrabRelease, KilledSimulationFadesTheForceWithinFiftyMillisecondsAndRestartResumes) {
  if (!InNetworkNamespace()) GTEST_SKIP() << kNeedsNetworkNamespace;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("costume_kill_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.toml") << HangingSheetScene(33, kStiffCottonCloth);
  // Rest 2 s, press and pull 10 cm out of the sheet and hold (the server is killed at 5 s
  // and restarted at 7 s with the cloth back at rest, 10 cm from the hand); at 9 s the hand
  // goes back to the cloth, lets go, grabs again at 10 s and pulls again by 11 s.
  std::ofstream(dir / "pull.traj") << "0.0 0 0 0 0\n2.0 0 0 0 0\n2.0 0 0 0 1\n3.0 0 0 0.10 1\n"
                                      "9.0 0 0 0.10 1\n9.5 0 0 0 1\n9.5 0 0 0 0\n10.0 0 0 0 0\n"
                                      "10.0 0 0 0 1\n11.0 0 0 0.10 1\n13.0 0 0 0.10 1\n";
  bus::LcmBus listener;
  struct Sample {
    int64_t utime;
    double force;
    int64_t patch_frame;
  };
  std::vector<Sample> feedback;
  bus::ReceivePolicy policy;
  policy.max_age_us = policy.max_lead_us = 0;  // keep everything: this test reads the times
  bus::Subscribe<costume_lcm::feedback>(
      listener, bus::kFeedbackChannel,
      [&feedback](const costume_lcm::feedback& f) {
        feedback.push_back({f.utime, Eigen::Vector3d(f.force[0], f.force[1], f.force[2]).norm(),
                            f.patch_frame});
      },
      policy);
  int64_t last_patch_utime = 0;
  bus::Subscribe<costume_lcm::haptic_patch>(
      listener, bus::kHapticPatchChannel,
      [&last_patch_utime](const costume_lcm::haptic_patch& p) { last_patch_utime = p.utime; },
      policy);
  auto listen = [&listener](double seconds) {
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(static_cast<int>(seconds * 1000));
    while (std::chrono::steady_clock::now() < until) listener.HandleSubscriptions(10);
  };
  const std::string root = COSTUME_BUILD_DIR;
  const std::vector<std::string> sim_args = {root + "/sim_core/app/costume_sim_server", "--scene",
                                             (dir / "scene.toml").string(), "--editing"};
  bool sim_up = false;
  bus::Subscribe<costume_lcm::status>(listener, bus::kSimStatusChannel,
                                      [&sim_up](const costume_lcm::status&) { sim_up = true; });
  pid_t sim = Spawn(sim_args);
  // The device's clock starts with the haptic server: start it once the server is up.
  for (int i = 0; i < 1200 && !sim_up; ++i) listener.HandleSubscriptions(50);
  const pid_t haptic = Spawn({root + "/haptic_server/costume_haptic_server", "--device",
                              "simulated", "--trajectory", (dir / "pull.traj").string(),
                              "--offset", "0", "-0.5", "-0.5", "--seconds", "12", "--priority",
                              "0"});
  listen(5.0);  // grabbed at 2 s, stretched by 3 s
  ASSERT_FALSE(feedback.empty());
  // The strongest force since a time on the device's clock (its ticks are stamped on an
  // absolute clock from its start, the first sample) [s]: on a loaded machine a late patch
  // fades the force for a moment (ForceSafety's stale-patch fade), which is not what is
  // tested here, so a window of a second or more is judged by its strongest force.
  auto strongest_since = [&feedback](double device_seconds) {
    const std::int64_t since_utime =
        feedback.front().utime + static_cast<std::int64_t>(device_seconds * 1e6);
    double strongest = 0.0;
    for (const Sample& s : feedback) {
      if (s.utime >= since_utime) strongest = std::max(strongest, s.force);
    }
    return strongest;
  };
  const double held = strongest_since(3.0);  // from the end of the pull to the kill
  kill(sim, SIGKILL);
  Wait(sim);
  const std::size_t killed_at = feedback.size();
  listen(2.0);
  // The killed server's last patch, read once the listener has taken in what was on its way
  // at the kill: read at the kill, under load it was a patch or more older (the listener
  // 17 ms behind), and the fade seemed to end 67 ms after it.
  const int64_t last_patch = last_patch_utime;
  // The first zero force after the kill, measured from the last patch that arrived.
  int64_t zero_at = -1;
  for (std::size_t i = killed_at; i < feedback.size(); ++i) {
    if (feedback[i].force == 0.0) {
      zero_at = feedback[i].utime;
      break;
    }
  }
  sim = Spawn(sim_args);  // the server comes back at 7 s
  // The hand grabs again at 10 s and pulls by 11 s: listen until the device's 12 s are over,
  // however long a loaded machine takes. (Listening a fixed 4.5 s of wall time and judging
  // its last 0.5 s failed once in a full ctest -j2 run whose load made the loop miss 14 % of
  // its ticks: no force in that half second.)
  int haptic_exit = -1;
  bool haptic_ended = false;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!haptic_ended && std::chrono::steady_clock::now() < give_up) {
    listener.HandleSubscriptions(10);
    int status = 0;
    if (waitpid(haptic, &status, WNOHANG) == haptic) {
      haptic_ended = true;
      haptic_exit = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
  }
  if (!haptic_ended) {  // its SIGTERM exit status would hide the hang: -1 stays
    ADD_FAILURE() << "the haptic server did not end its 12 s within 60 s";
    Terminate(haptic);
  }
  const double resumed = strongest_since(10.5);  // half way through the pull, to the end
  EXPECT_EQ(haptic_exit, 0);
  kill(sim, SIGTERM);
  Wait(sim);
  std::filesystem::remove_all(dir);
  std::printf("force held %.3f N; zero %.1f ms after the last patch; %.3f N after the restart\n",
              held, (zero_at - last_patch) / 1e3, resumed);
  EXPECT_GT(held, 0.05);
  ASSERT_GE(zero_at, 0) << "the force never reached zero after the kill";
  // The safety property: no force is commanded later than 50 ms after the last patch (plus
  // one 250 Hz publication). Asserted on the samples, not on when the first zero came: on a
  // loaded machine the 1 kHz loop (normal priority here) may skip ticks, so the first tick
  // after the deadline can come a few ms late — with zero force, which is what matters.
  for (std::size_t i = killed_at; i < feedback.size() && feedback[i].utime < last_patch + 2'000'000;
       ++i) {
    if (feedback[i].utime > last_patch + 50'000 + 4'000) {
      EXPECT_EQ(feedback[i].force, 0.0) << (feedback[i].utime - last_patch) / 1e3
                                        << " ms after the last patch";
    }
  }
  EXPECT_GT(resumed, 0.05);
}

}  // namespace
}  // namespace costume
