/// @file
/// costume_designer: the Qt front-end (docs/frontend.md). Starts the simulation server and
/// the haptic server with the chosen device as child processes (unless --no-servers), talks
/// to them over LCM, and stops them when the window closes.

#include <CLI/CLI.hpp>
#include <QApplication>
#include <QScreen>
#include <QTimer>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bus/lcm_bus.h"
#include "frontend/main_window.h"
#include "sim_core/common/input_error.h"

namespace {

std::atomic<bool> g_stop{false};

void OnSignal(int) { g_stop.store(true); }

struct Arguments {
  std::string lcm_url = costume::bus::kDefaultLcmUrl;
  std::string builtin = "garment";
  std::string scene;
  std::string device = "mouse";
  std::string catalog;
  std::string bin_dir = COSTUME_BUILD_DIR;
  std::string trajectory = std::string(COSTUME_SOURCE_DIR) + "/scenes/haptics/press_and_pull.traj";
  double radius = 0.05;
  bool no_servers = false;
  bool editing = false;
  bool allow_network = false;
  std::string screenshot;
  double quit_after = 0.0;
};

/// The first of the arguments CLI11 left over that Qt would not take either: anything with two
/// dashes (a mistyped option of ours) or a bare word not following a one-dash Qt option
/// (-platform xcb); "" when there is none. Qt ignores what it does not know, so without
/// this check a typo would be dropped silently.
std::string RefusedExtra(const std::vector<std::string>& extras) {
  bool value_allowed = false;
  for (const std::string& extra : extras) {
    const bool one_dash = extra.size() > 1 && extra[0] == '-' && extra[1] != '-';
    if (extra.rfind("--", 0) == 0 || (!one_dash && !value_allowed)) return extra;
    value_allowed = one_dash;
  }
  return "";
}

int Run(QApplication& app, const Arguments& args) {
  using namespace costume;
  bus::LcmBus bus(args.lcm_url,
                  args.allow_network ? bus::Reach::kNetwork : bus::Reach::kThisHost);
  frontend::FrontendOptions options;
  options.builtin = args.builtin;
  options.scene_file = args.scene;
  options.start_sim_server = !args.no_servers;
  options.device = args.no_servers || args.device == "none" ? QString()
                                                            : QString::fromStdString(args.device);
  options.servers.bin_dir = QString::fromStdString(args.bin_dir);
  options.servers.lcm_url = QString::fromStdString(bus.url());
  options.servers.allow_network = args.allow_network;
  options.servers.builtin = QString::fromStdString(args.builtin);
  options.servers.scene_file = QString::fromStdString(args.scene);
  options.servers.trajectory = QString::fromStdString(args.trajectory);
  options.servers.catalog_url = QString::fromStdString(args.catalog);  // same ids as the lists
  options.servers.radius = args.radius;
  options.servers.editing = args.editing;
  std::string warning;
  auto catalog = frontend::OpenCatalogSource(args.catalog, &warning);
  frontend::MainWindow window(bus, options, std::move(catalog));
  if (!warning.empty()) window.Warn(QString::fromStdString(warning));
  // 1280 × 860 where it fits; on a smaller screen (a 1366 × 768 laptop) the screen's free
  // area, maximised: a fixed size put the status bar and the lists below its edge.
  const QSize wanted(1280, 860);
  const QScreen* screen = QGuiApplication::primaryScreen();
  const QSize room = screen ? screen->availableSize() : wanted;
  if (room.width() >= wanted.width() && room.height() >= wanted.height()) {
    window.resize(wanted);
    window.show();
  } else {
    window.resize(room);
    window.showMaximized();
  }
  window.StartBusThread();
  window.StartChildren();
  // SIGINT/SIGTERM close the window like the user would, so the servers stop cleanly.
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  QTimer stop_poll;
  QObject::connect(&stop_poll, &QTimer::timeout, &window, [&window] {
    if (g_stop.load()) window.close();
  });
  stop_poll.start(100);
  if (args.quit_after > 0.0) {
    // For scripted runs: a screenshot of the view, then close (children stopped).
    QTimer::singleShot(static_cast<int>(args.quit_after * 1000.0), &window, [&] {
      if (!args.screenshot.empty()) {
        const QString path = QString::fromStdString(args.screenshot);
        frontend::FrameExporter::Screenshot(window.view(), path);
        QString whole = path;
        whole.replace(".png", "_window.png");
        window.grab().save(whole, "PNG");  // the whole window beside the view alone
      }
      window.close();
    });
  }
  return app.exec();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"costume_designer: the Costume Designer workstation GUI (docs/frontend.md)"};
  Arguments args;
  cli.add_option("--lcm-url", args.lcm_url, "LCM URL")->capture_default_str();
  cli.add_flag("--allow-network", args.allow_network,
               "Accept a URL whose traffic leaves this machine (udpm ttl >= 1)");
  auto* scene = cli.add_option("--scene", args.scene, "Scene TOML file (server and view)");
  cli.add_option("--builtin", args.builtin, "Built-in scene: garment, demo, hang, drape")
      ->excludes(scene)
      ->capture_default_str();
  cli.add_option("--device", args.device,
                 "Device to connect at start: none, simulated, mouse, openhaptics, cybergrasp")
      ->check(CLI::IsMember({"none", "simulated", "mouse", "openhaptics", "cybergrasp"}))
      ->capture_default_str();
  cli.add_option("--trajectory", args.trajectory, "Trajectory of the simulated device")
      ->capture_default_str();
  cli.add_option("--radius", args.radius, "Grab radius [m]")->check(CLI::Range(0.005, 0.5));
  cli.add_option("--catalog", args.catalog, "Catalogue URL (default: $COSTUME_CATALOG or the "
                                            "per-user SQLite file)");
  cli.add_option("--bin-dir", args.bin_dir, "Build directory holding the server programs")
      ->capture_default_str();
  cli.add_flag("--no-servers", args.no_servers,
               "Start no server: connect to processes already on the bus");
  cli.add_flag("--editing", args.editing, "Start in editing mode (mode B)");
  cli.add_option("--quit-after", args.quit_after, "Close the window after this many seconds")
      ->check(CLI::NonNegativeNumber);
  cli.add_option("--screenshot", args.screenshot, "With --quit-after: save the 3D view as PNG (and the window as *_window.png)");
  cli.allow_extras();  // Qt's own options (-platform, -style, ...) go to QApplication
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    return cli.exit(error);  // --help works without a display: no QApplication yet
  }
  if (const std::string refused = RefusedExtra(cli.remaining()); !refused.empty()) {
    std::fprintf(stderr, "costume_designer: unknown option or argument '%s' (see --help; Qt's "
                 "own options take one dash, e.g. -platform xcb)\n", refused.c_str());
    return 2;
  }
  QApplication app(argc, argv);
  if (QGuiApplication::platformName() == "offscreen") {
    // Qt 6.4's offscreen platform crashes flushing a window that holds a QOpenGLWidget (the
    // 3D view; docs/frontend.md): a segmentation fault is no answer to an option.
    std::fprintf(stderr, "costume_designer: the Qt platform 'offscreen' cannot show the 3D view "
                 "(Qt crashes drawing its OpenGL widget there); run it on a display or under "
                 "xvfb-run, or run `bash scripts/demo.sh --headless` for the simulation without a "
                 "window\n");
    return 2;
  }
  try {
    return Run(app, args);
  } catch (const costume::sim::InputError& error) {
    std::fprintf(stderr, "costume_designer: %s\n", error.what());
    return 2;
  }
}
