/// @file
/// costume_sim_server: the 60 Hz simulation process (docs/processes.md). Loads a scene (a
/// TOML file or a built-in one), then steps it on an absolute clock, taking grabs and
/// commands from LCM and publishing cloth frames, haptic patches and status.
/// SIGINT and SIGTERM stop it after the current frame.

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>

#include "assets/scene_file.h"
#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "catalog/catalog.h"
#include "sim_core/app/catalog_link.h"
#include "sim_core/app/grab_acknowledger.h"
#include "sim_core/app/sim_server.h"
#include "sim_core/common/input_error.h"

namespace {

std::atomic<bool> stop_requested{false};

void OnSignal(int) { stop_requested.store(true); }

struct Options {
  std::string scene_file;
  std::string builtin = "garment";
  std::string lcm_url;
  std::string catalog_url = costume::catalog::DefaultCatalogUrl();
  bool allow_network = false;
  bool paused = false;
  bool editing = false;
  long long frames = 0;
  int ack_priority = 70;
};

int Run(const Options& options) {
  costume::sim::SceneDescription scene = options.scene_file.empty()
                                             ? costume::assets::LoadBuiltInScene(options.builtin)
                                             : costume::assets::LoadSceneFile(options.scene_file);
  const auto reach =
      options.allow_network ? costume::bus::Reach::kNetwork : costume::bus::Reach::kThisHost;
  costume::bus::LcmBus bus(options.lcm_url, reach);
  costume::sim_app::SimServerOptions server_options;
  server_options.start_playing = !options.paused;
  server_options.mode =
      options.editing ? costume::sim_app::Mode::kEditing : costume::sim_app::Mode::kAnimation;
  // Opened at the first LOAD_* or SAVE_VERSION: a server without a catalogue still starts.
  server_options.catalog_url = costume::catalog::RedactedUrl(options.catalog_url);
  server_options.open_catalog = [url = options.catalog_url] {
    return costume::sim_app::OpenSceneCatalog(url);
  };
  std::printf("scene '%s' (%s): building...\n", scene.name.c_str(), scene.source.c_str());
  costume::sim_app::SimServer server(bus, scene, server_options);
  // Grab receipts from a receive thread of their own (haptic_bench's transport round trip).
  const costume::sim_app::GrabAcknowledger acknowledger(options.lcm_url, reach,
                                                       options.ack_priority);
  if (!acknowledger.priority_refusal().empty()) {
    server.SetStandingWarning(acknowledger.priority_refusal());
    std::printf("%s\n", acknowledger.priority_refusal().c_str());
  } else if (options.ack_priority > 0) {
    std::printf("grab acknowledger: SCHED_FIFO granted at priority %d\n", options.ack_priority);
  }
  if (scene.avatar && scene.avatar->clip) {
    std::printf("%s\n", costume::sim::DescribeArmSpread(server.simulation().arm_spread()).c_str());
  }
  namespace ch = costume::bus;
  std::printf("%d particles at %.0f Hz on %s\n"
              "  publishes %s, %s, %s\n  listens to %s, %s, %s\n",
              server.simulation().model().num_particles(), scene.frame_rate, bus.url().c_str(),
              ch::kClothFrameChannel.c_str(), ch::kHapticPatchChannel.c_str(),
              ch::kSimStatusChannel.c_str(), ch::kGrabChannel.c_str(),
              ch::kCommandChannel.c_str(), ch::kHapticCommandChannel.c_str());
  std::fflush(stdout);
  const long long steps = server.Run(stop_requested, options.frames);
  server.PublishStatus();
  std::printf("stopped after %lld frames (simulated frame %lld), %lld overruns\n", steps,
              static_cast<long long>(server.frame()),
              static_cast<long long>(server.overruns()));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"costume_sim_server: the 60 Hz cloth simulation process (docs/processes.md)"};
  Options options;
  auto* file = app.add_option("--scene", options.scene_file, "Scene TOML file");
  app.add_option("--builtin", options.builtin, "Built-in scene when no --scene is given")
      ->excludes(file)
      ->capture_default_str();
  app.add_option("--lcm-url", options.lcm_url,
                 "LCM URL; default $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0");
  app.add_option("--catalog", options.catalog_url,
                 "Catalogue URL for LOAD_* and SAVE_VERSION (sqlite:<path> or postgresql://...); "
                 "opened at the first such command")
      ->capture_default_str();
  app.add_flag("--allow-network", options.allow_network,
               "Accept a URL whose traffic leaves this machine (udpm ttl >= 1)");
  app.add_option("--frames", options.frames, "Stop after this many frames (0: run until a signal)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--ack-priority", options.ack_priority,
                 "SCHED_FIFO priority of the grab-ack receive thread, below the haptic tick's 80 "
                 "(<= 0: normal priority)")
      ->check(CLI::Range(-99, 99))
      ->capture_default_str();
  app.add_flag("--paused", options.paused, "Start stopped at frame 0 (send PLAY to run)");
  app.add_flag("--editing", options.editing, "Start in mode B (editing) instead of mode A");
  CLI11_PARSE(app, argc, argv);

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  try {
    return Run(options);
  } catch (const costume::sim::InputError& error) {
    std::fprintf(stderr, "costume_sim_server: %s\n", error.what());
    return 2;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "costume_sim_server: error: %s\n", error.what());
    return 1;
  }
}
