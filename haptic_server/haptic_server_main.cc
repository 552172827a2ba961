// costume_haptic_server: the 1 kHz haptic process (issue 5; haptic_server/README.md,
// "The process"). Opens one device, runs the tick at 1 kHz (SCHED_FIFO when permitted) and
// the LCM I/O thread beside it, until SIGINT/SIGTERM or --seconds; on the way out the grab is
// released so the force fades to zero before the device is closed.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bus/lcm_bus.h"
#include "haptic_server/haptic_server_io.h"
#include "haptic_server/log_playback_device.h"
#include "haptic_server/mouse_device.h"
#include "haptic_server/simulated_device.h"
#include "sim_core/common/input_error.h"
#ifdef COSTUME_HAVE_OPENHAPTICS
#include "haptic_server/openhaptics_device.h"
#endif
#ifdef COSTUME_HAVE_CYBERGRASP
#include "haptic_server/cybergrasp_device.h"
#endif

namespace {

using namespace costume;
using namespace costume::haptics;

std::atomic<bool> g_stop{false};

void OnSignal(int) { g_stop.store(true); }

void InstallSignalHandlers() {
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

struct Arguments {
  std::string device = "simulated";
  std::string trajectory;
  std::string device_log;
  std::string openhaptics_name;
  double radius = 0.05;
  double coupling = 200.0;
  std::string lcm_url;
  bool allow_network = false;
  double seconds = 0.0;
  double scale = 1.0;
  std::vector<double> offset{0.0, 0.0, 0.0};
  int publish_every = 4;
  int priority = 80;
  int io_priority = 70;
  int spin_us = static_cast<int>(kDefaultSpinMargin / 1000);
};

/// The loop's period here (1 kHz) and so the largest --spin-us.
constexpr std::int64_t kPeriodNs = 1'000'000;
constexpr int kMaxSpinUs = static_cast<int>(kMaxSpinMarginFraction * kPeriodNs / 1000);

/// The device named on the command line. Throws InputError with what to do instead.
std::unique_ptr<HapticDevice> MakeDevice(const Arguments& args) {
  if (args.device == "simulated") {
    if (args.trajectory.empty()) {
      throw sim::InputError("--device simulated needs --trajectory FILE (format: "
                            "haptic_server/simulated_device.h; example: scenes/haptics/)");
    }
    return std::make_unique<SimulatedDevice>(LoadTrajectory(args.trajectory));
  }
  if (args.device == "playback") {
    if (args.device_log.empty()) {
      throw sim::InputError("--device playback needs --device-log FILE (format: "
                            "haptic_server/log_playback_device.h)");
    }
    return std::make_unique<LogPlaybackDevice>(LoadDeviceLog(args.device_log));
  }
  if (args.device == "mouse") {
    // Fed from COSTUME_POINTER by the I/O thread (HapticServerIo::SetPointerDevice).
    return std::make_unique<MouseDevice>();
  }
  if (args.device == "openhaptics") {
#ifdef COSTUME_HAVE_OPENHAPTICS
    return std::make_unique<OpenHapticsDevice>(args.openhaptics_name);
#else
    throw sim::InputError(
        "--device openhaptics: this build has no OpenHaptics support (HD/hd.h and libHD were "
        "not found at configure time); install the OpenHaptics SDK and reconfigure with "
        "-DCOSTUME_WITH_OPENHAPTICS=ON (hints: OPENHAPTICS_ROOT, env OH_SDK_BASE)");
#endif
  }
  if (args.device == "cybergrasp") {
#ifdef COSTUME_HAVE_CYBERGRASP
    return std::make_unique<CyberGraspDevice>();
#else
    throw sim::InputError(
        "--device cybergrasp: this build has no CyberGrasp support (the VirtualHand SDK was "
        "not found at configure time); install it and reconfigure with "
        "-DCOSTUME_WITH_CYBERGRASP=ON (hints: CYBERGRASP_ROOT, env VHT_HOME)");
#endif
  }
  throw sim::InputError("--device '" + args.device +
                        "': allowed simulated, mouse, playback, openhaptics, cybergrasp");
}

void PrintRealtime(const HapticLoop& loop) {
  for (int i = 0; i < 1000 && loop.counters().num_ticks == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const RealtimeStatus rt = loop.realtime_status();
  if (rt.realtime) {
    std::printf("real-time: SCHED_FIFO granted at priority %d, memory %s\n", rt.priority,
                rt.memory_locked ? "locked" : "NOT locked");
  } else {
    std::printf("real-time: SCHED_FIFO NOT granted: running at normal priority\n");
  }
  if (!rt.reason.empty()) std::printf("real-time: %s\n", rt.reason.c_str());
  const KernelPreemption preemption = ReadKernelPreemption();
  const std::string warning = KernelPreemptionWarning(preemption);
  if (!warning.empty()) {
    std::printf("real-time: %s\n", warning.c_str());
  } else if (!preemption.model.empty()) {
    std::printf("real-time: kernel preemption '%s' (from %s)\n", preemption.model.c_str(),
                preemption.source.c_str());
  }
  std::fflush(stdout);
}

/// How the loop waits (after PrintRealtime: spinning is off at normal priority).
void PrintPacing(const HapticLoop& loop, int spin_us) {
  if (loop.spin_margin() > 0) {
    std::printf("pacing: sleep until %lld us before each deadline, then spin on CLOCK_MONOTONIC\n",
                static_cast<long long>(loop.spin_margin() / 1000));
  } else if (spin_us > 0) {
    std::printf("pacing: sleep until each deadline (--spin-us %d unused: no real-time priority)\n",
                spin_us);
  } else {
    std::printf("pacing: sleep until each deadline (--spin-us 0)\n");
  }
  std::fflush(stdout);
}

int Run(const Arguments& args) {
  sim::RequireNonNegative("--seconds", args.seconds, "s");
  WorkspaceTransform workspace;
  workspace.scale = args.scale;
  workspace.offset = Eigen::Vector3d(args.offset[0], args.offset[1], args.offset[2]);
  workspace.Validate("workspace", "--scale", "--offset");

  // Before the device is opened: a refused URL leaves no device running.
  auto lcm_bus = std::make_unique<bus::LcmBus>(
      args.lcm_url, args.allow_network ? bus::Reach::kNetwork : bus::Reach::kThisHost);
  bus::LcmBus& lcm = *lcm_bus;
  std::unique_ptr<HapticDevice> inner = MakeDevice(args);
  ReleasableDevice device(*inner);
  const DeviceStatus opened = device.Open();
  if (!opened.ok) {
    std::fprintf(stderr, "costume_haptic_server: cannot open %s: %s\n", device.name().c_str(),
                 opened.message.c_str());
    return 1;
  }
  std::printf("costume_haptic_server: device %s, LCM %s, radius %g m\n", device.name().c_str(),
              lcm.url().c_str(), args.radius);

  MonotonicClock clock;
  PatchMailbox patches;
  OutgoingQueue outgoing;
  HapticServerIoOptions io_options;
  io_options.radius = args.radius;
  io_options.coupling_stiffness = args.coupling;
  io_options.publish_every = args.publish_every;
  io_options.io_priority = args.io_priority;
  // Constructed before the tick runs: it reserves the patch slots the tick reads.
  HapticServerIo io(lcm, clock, patches, outgoing, device, workspace, io_options);
  HapticTick tick(device, patches, outgoing, workspace, ForceSafetyOptions{});
  TimedTickHandler timed(tick, clock);
  HapticLoopOptions loop_options;
  loop_options.period = kPeriodNs;
  loop_options.realtime_priority = args.priority;
  loop_options.spin_margin = static_cast<std::int64_t>(args.spin_us) * 1000;
  HapticLoop loop(clock, timed, loop_options);
  io.SetStatusSources(&loop, &tick, &timed);
  if (auto* mouse = dynamic_cast<MouseDevice*>(inner.get())) io.SetPointerDevice(mouse);

  InstallSignalHandlers();
  const auto start = std::chrono::steady_clock::now();
  loop.Start();
  io.Start();
  PrintRealtime(loop);
  PrintPacing(loop, args.spin_us);

  while (!g_stop.load()) {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (args.seconds > 0.0 && elapsed >= args.seconds) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }

  // Release the grab and let ForceSafety fade the force out (fade_time 25 ms) before stopping.
  device.ReleaseGrab();
  const double fade = tick.safety().options().fade_time;
  std::this_thread::sleep_for(std::chrono::duration<double>(2.0 * fade + 0.01));
  loop.Stop();
  io.Stop();
  io.PublishStatus();
  const DeviceStatus closed = device.Close();
  if (!closed.ok) std::fprintf(stderr, "close: %s\n", closed.message.c_str());

  const double run_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const LoopCounters c = loop.counters();
  const PacerCounters pacing = loop.pacer_counters();
  const PeriodStatistics p = loop.Statistics();
  const HapticServerIoCounts& n = io.counts();
  std::printf("stopped: %lld ticks, %lld missed, %lld overruns; period p99 %.1f us, max %.1f us; "
              "final force %.3g N; %lld patches, %lld grabs published\n",
              static_cast<long long>(c.num_ticks), static_cast<long long>(c.num_missed),
              static_cast<long long>(c.num_overruns), p.p99 * 1e-3, p.max * 1e-3,
              tick.last_device_force().norm(), static_cast<long long>(n.num_patches_handed),
              static_cast<long long>(n.num_grabs_published));
  if (loop.spin_margin() > 0) {
    std::printf("pacing: spinning took %.1f %% of a core; %lld of %lld sleeps woke past the "
                "deadline (latency over %d us)\n",
                100.0 * static_cast<double>(pacing.spin_ns) * 1e-9 / std::max(run_seconds, 1e-9),
                static_cast<long long>(pacing.num_margin_exceeded),
                static_cast<long long>(pacing.num_waits), args.spin_us);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"costume_haptic_server: the 1 kHz haptic process (haptic_server/README.md)"};
  Arguments args;
  app.add_option("--device", args.device, "simulated | mouse | playback | openhaptics | cybergrasp")
      ->capture_default_str();
  app.add_option("--trajectory", args.trajectory,
                 "simulated device: scripted trajectory file (time x y z buttons per line)");
  app.add_option("--device-log", args.device_log, "playback device: recorded device log file");
  app.add_option("--openhaptics-device", args.openhaptics_name,
                 "OpenHaptics device configuration name (empty: the default device)");
  app.add_option("--radius", args.radius, "grab sphere radius [m]")
      ->check(CLI::Range(costume::haptics::kMinRadius, costume::haptics::kMaxRadius))
      ->capture_default_str();
  app.add_option("--coupling", args.coupling,
                 "stiffness of the simulation's implicit grab coupling [N/m]; 0 sends F_h as a "
                 "force instead")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  app.add_option("--lcm-url", args.lcm_url,
                 "LCM URL (empty: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0)");
  // The same flag as the simulation server's and the GUI's; --lan is its older name.
  app.add_flag("--allow-network,--lan", args.allow_network,
               "Accept an LCM URL whose traffic leaves this machine (udpm ttl >= 1, tcpq to "
               "another host)");
  app.add_option("--seconds", args.seconds, "stop after this many seconds (0: until a signal)")
      ->check(CLI::Range(0.0, 1e9))  // a NaN, which Range lets through, is refused in Run
      ->capture_default_str();
  app.add_option("--scale", args.scale,
                 "workspace scale: scene metres per device metre, " +
                     sim::FormatValue(haptics::WorkspaceTransform::kMinScale) + " to " +
                     sim::FormatValue(haptics::WorkspaceTransform::kMaxScale))
      ->capture_default_str();
  app.add_option("--offset", args.offset,
                 "scene position of the device origin x y z [m], each within ±" +
                     sim::FormatValue(sim::kMaxCoordinate))
      ->expected(3);
  app.add_option("--publish-every", args.publish_every,
                 "publish device_state, feedback, grab every n ticks (4: 250 Hz)")
      ->capture_default_str();
  app.add_option("--priority", args.priority, "SCHED_FIFO priority, 1..99 (<= 0: normal)")
      ->check(CLI::Range(-99, 99))
      ->capture_default_str();
  app.add_option("--io-priority", args.io_priority,
                 "SCHED_FIFO priority of the LCM I/O thread, below the tick's (<= 0: normal)")
      ->check(CLI::Range(-99, 99))
      ->capture_default_str();
  app.add_option("--spin-us", args.spin_us,
                 "pacing: sleep until this many us before each 1 ms deadline, then spin reading "
                 "the clock until it (absorbs the sleep's wake-up latency at the cost of up to "
                 "this much CPU per period); 0 sleeps all the way")
      ->check(CLI::Validator(
          [](std::string& value) -> std::string {
            int us = 0;
            const auto [end, error] = std::from_chars(value.data(), value.data() + value.size(), us);
            if (error == std::errc() && end == value.data() + value.size() && us >= 0 &&
                us <= kMaxSpinUs) {
              return "";
            }
            return "'" + value + "' refused: whole microseconds from 0 (sleep only) to " +
                   std::to_string(kMaxSpinUs) +
                   " (half the 1 ms period; beyond it the tick would spin most of each period)";
          },
          "0.." + std::to_string(kMaxSpinUs)))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(args);
  } catch (const sim::InputError& error) {
    std::fprintf(stderr, "costume_haptic_server: %s\n", error.what());
    return 2;
  }
}
