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
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <Eigen/Core>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/haptic_patch.hpp"

extern char** environ;

namespace costume {
namespace {

/// Starts `argv` as a child process; returns its pid.
pid_t Spawn(std::vector<std::string> argv) {
  std::vector<char*> args;
  for (std::string& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  pid_t pid = 0;
  EXPECT_EQ(posix_spawn(&pid, args[0], nullptr, nullptr, args.data(), environ), 0) << argv[0];
  return pid;
}

/// Waits for `pid`; returns its exit status, or −1 when it did not exit normally.
int Wait(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// The cloth's frames as they arrive: frame number → position of one watched particle.
struct FrameLog {
  int particle = 0;
  std::map<int64_t, Eigen::Vector3d> positions;
  void OnFrame(const costume_lcm::cloth_frame& frame) {
    const int i = particle - frame.first_particle;
    if (i < 0 || i >= frame.num_particles) return;
    positions[frame.frame] = Eigen::Vector3d(frame.x[i], frame.y[i], frame.z[i]);
  }
};

TEST(GrabRelease, PulledClothFollowsTheDeviceAndReturnsToRestWhenReleased) {
  if (std::getenv("COSTUME_IN_NETNS") == nullptr) {
    GTEST_SKIP() << "run through ctest: it needs a private network namespace";
  }
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "costume_grab_test";
  std::filesystem::create_directories(dir);
  // A 1 m sheet (33 × 33, stiff cotton) built already hanging in the plane z = −0.5 from its
  // two top corners, so it is near rest from the start; its middle is near (0, −0.5, −0.5).
  // The device origin is put there; the trajectory rests 3 s (the sheet settles), presses,
  // pulls 10 cm along +z (out of the sheet) in 1 s, holds to 5 s, releases and waits to 9 s.
  const std::filesystem::path scene = dir / "hanging.toml";
  std::ofstream(scene) << "name = \"hanging\"\nduration = 10.0\n"
                          "[solver]\nmethod = \"pcg\"\ntolerance = 1e-3\n"
                          "[[garment]]\nname = \"sheet\"\nmaterial = \"stiff_cotton\"\n"
                          "pin_points = [[-0.5, 0, -0.5], [0.5, 0, -0.5]]\n"
                          "[garment.panel]\norigin = [-0.5, 0, -0.5]\nu_axis = [1, 0, 0]\n"
                          "v_axis = [0, -1, 0]\nsize = [1.0, 1.0]\nresolution = [33, 33]\n";
  const std::filesystem::path trajectory = dir / "pull.traj";
  std::ofstream(trajectory) << "# time x y z buttons\n"
                               "0.0 0 0 0 0\n3.0 0 0 0 0\n3.0 0 0 0 1\n4.0 0 0 0.10 1\n"
                               "5.0 0 0 0.10 1\n5.0 0 0 0.10 0\n9.0 0 0 0.10 0\n";
  bus::LcmBus listener;
  FrameLog log;
  log.particle = 16 * 33 + 16;  // the middle of the sheet
  bus::Subscribe<costume_lcm::cloth_frame>(
      listener, bus::kClothFrameChannel,
      [&log](const costume_lcm::cloth_frame& frame) { log.OnFrame(frame); });

  int grabs = 0, patches = 0;
  double strongest = 0.0;
  bus::Subscribe<costume_lcm::grab>(listener, bus::kGrabChannel,
                                    [&](const costume_lcm::grab& grab) {
                                      if (grab.mode != costume_lcm::grab::MODE_GRAB) return;
                                      ++grabs;
                                      strongest = std::max(strongest, Eigen::Vector3d(grab.force[0], grab.force[1], grab.force[2]).norm());
                                    });
  bus::Subscribe<costume_lcm::haptic_patch>(
      listener, bus::kHapticPatchChannel, [&](const costume_lcm::haptic_patch&) { ++patches; });

  const std::string root = COSTUME_BUILD_DIR;
  const pid_t sim = Spawn({root + "/sim_core/app/costume_sim_server", "--scene", scene.string(),
                           "--editing", "--frames", "540"});
  const pid_t haptic = Spawn({root + "/haptic_server/costume_haptic_server", "--device",
                              "simulated", "--trajectory", trajectory.string(), "--offset", "0",
                              "-0.5", "-0.5", "--seconds", "9", "--priority", "0"});
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < until && log.positions.size() < 540) {
    listener.HandleSubscriptions(50);
  }
  EXPECT_EQ(Wait(haptic), 0);
  EXPECT_EQ(Wait(sim), 0);
  ASSERT_GE(log.positions.size(), 500u) << "cloth frames lost";

  auto at = [&log](double seconds) {  // the watched particle at a time (nearest frame)
    const auto found = log.positions.lower_bound(static_cast<int64_t>(seconds * 60));
    return found == log.positions.end() ? log.positions.rbegin()->second : found->second;
  };
  const Eigen::Vector3d rest = at(2.9), pulled = at(4.9), released = at(8.9);
  std::printf("middle particle z: rest %.4f m, pulled %.4f m, 4 s after release %.4f m; "
              "%d grab messages (strongest F_h %.3f N), %d patch chunks\n",
              rest.z(), pulled.z(), released.z(), grabs, strongest, patches);
  // The device held the button 2 s at 250 Hz: ~500 grab messages; the simulation answered
  // every frame of it with a patch (one chunk each for this small selection).
  EXPECT_GT(grabs, 400);
  EXPECT_GT(patches, 100);
  EXPECT_TRUE(std::isfinite(strongest));
  EXPECT_GT(pulled.z() - rest.z(), 0.08);                               // followed the 10 cm pull
  EXPECT_LT((released - rest).norm(), 0.1 * (pulled - rest).norm());  // and came back
}

}  // namespace
}  // namespace costume
