/// @file
/// replay: feeds a recorded session (an `lcm-logger` log) back to the simulation server and
/// checks that it reproduces the recorded cloth frames bit for bit (issue 5).
///
/// Each recorded cloth_frame says which inputs its step had taken in (grab_seq, command_seq,
/// haptic_command_seq); the replay builds a SimServer for the same scene on an in-process
/// memq:// bus and, before the step of each recorded frame, hands it every logged grab and
/// command up to those sequence numbers, in log order. The server then sees the same inputs in
/// the same frames as the live one, and its deterministic step gives the same floats.
/// Inputs the live server dropped (stale: utime more than 1 s before or after its arrival;
/// out of order: a seq that did not increase) must be dropped again, and only they: each
/// input goes through the server's own receive filter, one at a time and in the recorded
/// receive order, with the filter's clock set to the time lcm-logger received it (the log
/// event's timestamp), not the wall clock of the replay. A message within a few milliseconds
/// of the age limit could fall either way (the logger and the server received it at slightly
/// different times); everything clearly stale or out of order is decided as it was live.
///
/// Exit status: 0 when every compared frame is identical; 3 when frames differ after an input
/// the live server took in that the log lacks (lcm-logger missed it; the message says which);
/// 1 when they differ otherwise; 2 for a bad log or scene.

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "assets/scene_file.h"
#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/grab.hpp"
#include "sim_core/app/sim_server.h"
#include "sim_core/common/input_error.h"

namespace {

using namespace costume;

/// One logged input message, its channel, its seq and when the logger received it.
struct Input {
  std::string channel;
  std::vector<std::uint8_t> bytes;
  std::int64_t seq = 0;
  /// lcm-logger's receive time [µs since the Unix epoch].
  std::int64_t received = 0;
};

/// A recorded frame: its positions (all chunks) and the inputs its step had seen.
struct RecordedFrame {
  std::vector<float> x, y, z;
  std::int64_t grab_seq = -1, command_seq = -1, haptic_command_seq = -1;
  std::int8_t mode = 0;
  int chunks_seen = 0, num_chunks = 1;
};

template <class Message>
bool Decode(const lcm::LogEvent& event, Message& message) {
  return message.decode(event.data, 0, event.datalen) == event.datalen;
}

/// Adds one chunk of a logged cloth_frame.
void AddChunk(const costume_lcm::cloth_frame& chunk, std::map<std::int64_t, RecordedFrame>& frames) {
  RecordedFrame& frame = frames[chunk.frame];
  frame.x.resize(chunk.total_particles);
  frame.y.resize(chunk.total_particles);
  frame.z.resize(chunk.total_particles);
  std::copy(chunk.x.begin(), chunk.x.end(), frame.x.begin() + chunk.first_particle);
  std::copy(chunk.y.begin(), chunk.y.end(), frame.y.begin() + chunk.first_particle);
  std::copy(chunk.z.begin(), chunk.z.end(), frame.z.begin() + chunk.first_particle);
  frame.grab_seq = chunk.grab_seq;
  frame.command_seq = chunk.command_seq;
  frame.haptic_command_seq = chunk.haptic_command_seq;
  frame.mode = chunk.mode;
  frame.num_chunks = chunk.num_chunks;
  ++frame.chunks_seen;
}

/// Reads the log: the inputs in log order and the complete recorded frames.
void ReadLog(const std::string& path, std::vector<Input>& inputs,
             std::map<std::int64_t, RecordedFrame>& frames) {
  lcm::LogFile log(path, "r");
  if (!log.good()) throw sim::InputError(path + ": cannot open the LCM log");
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    if (event->channel == bus::kClothFrameChannel) {
      costume_lcm::cloth_frame chunk;
      if (Decode(*event, chunk)) AddChunk(chunk, frames);
      continue;
    }
    Input input{event->channel, {}, 0, event->timestamp};
    if (event->channel == bus::kGrabChannel) {
      costume_lcm::grab grab;
      if (!Decode(*event, grab)) continue;
      input.seq = grab.seq;
    } else if (event->channel == bus::kCommandChannel ||
               event->channel == bus::kHapticCommandChannel) {
      costume_lcm::command command;
      if (!Decode(*event, command)) continue;
      input.seq = command.seq;
    } else {
      continue;
    }
    const auto* data = static_cast<const std::uint8_t*>(event->data);
    input.bytes.assign(data, data + event->datalen);
    inputs.push_back(std::move(input));
  }
  std::erase_if(frames, [](const auto& entry) {
    return entry.second.chunks_seen != entry.second.num_chunks;
  });
}

/// The seq bound of `channel` for a frame.
std::int64_t BoundFor(const RecordedFrame& frame, const std::string& channel) {
  if (channel == bus::kGrabChannel) return frame.grab_seq;
  if (channel == bus::kCommandChannel) return frame.command_seq;
  return frame.haptic_command_seq;
}

/// The first input the live server had taken in that the log lacks: a frame names a seq as
/// its step's last one, and no logged message on that channel carries it. lcm-logger is a
/// normal-priority process with its own socket and may miss a message under load; the
/// frames from there on cannot be reproduced from the log.
struct MissingInput {
  std::string channel;
  std::int64_t seq = -1, frame = -1;
};

std::optional<MissingInput> FirstMissingInput(const std::vector<Input>& inputs,
                                              const std::map<std::int64_t, RecordedFrame>& frames) {
  std::map<std::string, std::set<std::int64_t>> logged;
  for (const Input& input : inputs) logged[input.channel].insert(input.seq);
  std::map<std::string, std::int64_t> previous;
  for (const auto& [number, frame] : frames) {
    for (const std::string& channel :
         {bus::kGrabChannel, bus::kCommandChannel, bus::kHapticCommandChannel}) {
      const std::int64_t bound = BoundFor(frame, channel);
      const auto before = previous.find(channel);
      const bool newly_taken = before == previous.end() || bound != before->second;
      previous[channel] = bound;
      if (newly_taken && bound >= 0 && !logged[channel].contains(bound)) {
        return MissingInput{channel, bound, number};
      }
    }
  }
  return std::nullopt;
}

/// Exit status when frames differ after an input the log lacks (FirstMissingInput).
constexpr int kIncompleteLog = 3;

struct Options {
  std::string log, scene_file, builtin = "garment";
  /// The live server's acceptance window (bus::ReceivePolicy's defaults) [µs].
  std::int64_t max_age_us = bus::ReceivePolicy{}.max_age_us;
  std::int64_t max_lead_us = bus::ReceivePolicy{}.max_lead_us;
};

int Replay(const Options& options) {
  std::vector<Input> inputs;
  std::map<std::int64_t, RecordedFrame> recorded;
  ReadLog(options.log, inputs, recorded);
  if (recorded.empty()) throw sim::InputError(options.log + ": no complete cloth frame in the log");
  const sim::SceneDescription scene = options.scene_file.empty()
                                          ? assets::LoadBuiltInScene(options.builtin)
                                          : assets::LoadSceneFile(options.scene_file);
  bus::LcmBus memq("memq://");
  sim_app::SimServerOptions server_options;
  server_options.mode = recorded.begin()->second.mode == costume_lcm::cloth_frame::MODE_EDITING
                            ? sim_app::Mode::kEditing
                            : sim_app::Mode::kAnimation;
  // The live server's filter, on the log's clock: the receive time of the input at hand.
  std::int64_t log_now = 0;
  server_options.receive_policy.max_age_us = options.max_age_us;
  server_options.receive_policy.max_lead_us = options.max_lead_us;
  server_options.receive_policy.clock = [&log_now] { return log_now; };
  sim_app::SimServer server(memq, scene, server_options);
  std::map<std::int64_t, RecordedFrame> replayed;
  bus::ReceivePolicy keep_all;
  keep_all.max_age_us = keep_all.max_lead_us = 0;
  bus::Subscribe<costume_lcm::cloth_frame>(
      memq, bus::kClothFrameChannel,
      [&replayed](const costume_lcm::cloth_frame& chunk) { AddChunk(chunk, replayed); }, keep_all);

  std::size_t next_input = 0;
  const std::int64_t last = recorded.rbegin()->first;
  for (std::int64_t frame = 1; frame <= last; ++frame) {
    const auto it = recorded.find(frame);
    if (it != recorded.end()) {
      // Hand over every input this frame's step had taken in (earlier frames' too, if the
      // frames that named them were lost).
      // Each is dispatched at once, so the filter judges it at its own receive time; the
      // server's handlers only store it for the coming Step, as live.
      while (next_input < inputs.size() &&
             inputs[next_input].seq <= BoundFor(it->second, inputs[next_input].channel)) {
        log_now = inputs[next_input].received;
        memq.Publish(inputs[next_input].channel, inputs[next_input].bytes);
        memq.HandleSubscriptions(0);
        ++next_input;
      }
    }
    server.Step();
  }
  memq.HandleSubscriptions(0);
  int compared = 0, identical = 0;
  std::int64_t first_difference = -1;
  for (const auto& [frame, original] : recorded) {
    const auto found = replayed.find(frame);
    if (found == replayed.end()) continue;
    ++compared;
    const RecordedFrame& copy = found->second;
    const bool same = original.x.size() == copy.x.size() &&
                      std::memcmp(original.x.data(), copy.x.data(), 4 * copy.x.size()) == 0 &&
                      std::memcmp(original.y.data(), copy.y.data(), 4 * copy.y.size()) == 0 &&
                      std::memcmp(original.z.data(), copy.z.data(), 4 * copy.z.size()) == 0;
    if (same) {
      ++identical;
    } else if (first_difference < 0) {
      first_difference = frame;
    }
  }
  const bus::ReceiveCounts grabs = server.grab_counts();
  const bus::ReceiveCounts commands = server.command_counts();
  std::printf("replay: %zu inputs (dropped again: %lld stale, %lld out of order), %d recorded "
              "frames compared, %d identical bit for bit",
              inputs.size(), static_cast<long long>(grabs.stale + commands.stale),
              static_cast<long long>(grabs.out_of_order + commands.out_of_order), compared,
              identical);
  if (first_difference >= 0) std::printf(", first difference at frame %lld", static_cast<long long>(first_difference));
  std::printf("\n");
  if (compared > 0 && identical == compared) return 0;
  if (const std::optional<MissingInput> missing = FirstMissingInput(inputs, recorded);
      missing && (first_difference < 0 || missing->frame <= first_difference)) {
    std::printf("replay: the log lacks %s seq %lld, which the live server had taken in by frame "
                "%lld: lcm-logger missed it, and the frames from there on cannot be reproduced "
                "from this log\n",
                missing->channel.c_str(), static_cast<long long>(missing->seq),
                static_cast<long long>(missing->frame));
    return kIncompleteLog;
  }
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"replay: reproduce a recorded session's cloth frames from its logged inputs"};
  Options options;
  app.add_option("log", options.log, "LCM log written by lcm-logger")->required()->check(CLI::ExistingFile);
  auto* scene = app.add_option("--scene", options.scene_file, "Scene file the session ran")
                    ->check(CLI::ExistingFile);
  app.add_option("--builtin", options.builtin, "Built-in scene the session ran (default garment)")
      ->excludes(scene);
  // Within an hour either way: CLI11 saturates a number too large for 64 bits to the largest
  // one, which would pass unbounded as a limit nobody typed.
  const auto within_an_hour = CLI::Range(std::int64_t{-3'600'000'000}, std::int64_t{3'600'000'000});
  app.add_option("--max-age-us", options.max_age_us,
                 "The live server's stale limit for old utimes [µs] (<= 0: off)")
      ->check(within_an_hour)
      ->capture_default_str();
  app.add_option("--max-lead-us", options.max_lead_us,
                 "The live server's limit for utimes ahead of its clock [µs] (<= 0: off)")
      ->check(within_an_hour)
      ->capture_default_str();
  app.footer("Exit status: 0 every recorded frame reproduced bit for bit; 1 frames differ; 3 frames "
             "differ after an input the log lacks (lcm-logger missed it); 2 bad log or scene.");
  CLI11_PARSE(app, argc, argv);
  try {
    return Replay(options);
  } catch (const sim::InputError& error) {
    std::fprintf(stderr, "replay: %s\n", error.what());
    return 2;
  }
}
