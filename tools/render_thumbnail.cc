/// @file
/// render_thumbnail: renders one catalogue thumbnail offscreen (OSMesa, no display) and writes
/// it as a PNG, to look at what the database shows (docs/rendering.md). Exactly one of:
///   --avatar builtin|<avatar file>       the avatar in its rest pose
///   --clip <built-in clip>|<clip file>    the avatar (--on, default builtin) at mid-clip
///   --garment <pattern>|<scene .toml>     a garment on its avatar after a short fit
/// With --runs N it renders N times and prints the median time; one JSON line on stdout.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <vector>

#include "assets/avatar_import.h"
#include "assets/clip_import.h"
#include "assets/scene_file.h"
#include "render/thumbnails.h"
#include "sim_core/avatar/garment_patterns.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"

namespace {

using namespace costume;

/// Throws sim::InputError unless `name` is one of `built_ins` or an existing path: a name that
/// is neither is most likely a misspelt built-in, which "no such file" alone does not say.
void RequireBuiltInOrFile(const std::string& option, const std::string& name,
                          const std::vector<std::string>& built_ins) {
  std::error_code error;
  if (std::find(built_ins.begin(), built_ins.end(), name) != built_ins.end() ||
      std::filesystem::exists(name, error)) {
    return;
  }
  std::string names;
  for (const std::string& built_in : built_ins) names += (names.empty() ? "" : ", ") + built_in;
  throw sim::InputError(option + " '" + name + "': neither a built-in (" + names +
                        ") nor an existing file");
}

bool IsBuiltIn(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

std::shared_ptr<const sim::Avatar> AvatarNamed(const std::string& option,
                                               const std::string& name) {
  RequireBuiltInOrFile(option, name, {"builtin"});
  return name == "builtin" ? sim::MakeHumanoid() : assets::LoadAvatar(name);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Renders a catalogue thumbnail offscreen (OSMesa) into a PNG file."};
  std::string avatar, clip, garment, on = "builtin", out = "thumbnail.png";
  int size = 256, runs = 1;
  auto* avatar_option =
      app.add_option("--avatar", avatar, "builtin, or an avatar file (glTF, FBX, OBJ, ...)");
  auto* clip_option = app.add_option(
      "--clip", clip, "a built-in clip (stand, walk, run, jump, kick, dance) or a clip file");
  auto* garment_option = app.add_option(
      "--garment", garment, "a built-in garment (skirt, cape, dress) or a scene file (.toml)");
  avatar_option->excludes(clip_option, garment_option);
  clip_option->excludes(garment_option);
  app.add_option("--on", on, "the avatar a --clip is shown on: builtin or an avatar file");
  app.add_option("--size", size, "width = height [px]")->check(CLI::Range(16, 4096));
  app.add_option("--out", out, "PNG file to write")->capture_default_str();
  app.add_option("--runs", runs, "render this many times, report the median time")
      ->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  if (avatar.empty() && clip.empty() && garment.empty()) {
    std::cerr << "error: give one of --avatar, --clip, --garment (see --help)\n";
    return 2;
  }
  try {
    std::function<render::Image()> render_once;
    std::string kind;
    if (!avatar.empty()) {
      kind = "avatar";
      auto model = AvatarNamed("--avatar", avatar);
      render_once = [model, size] { return render::RenderAvatarThumbnail(*model, size); };
    } else if (!clip.empty()) {
      kind = "clip";
      auto model = AvatarNamed("--on", on);
      RequireBuiltInOrFile("--clip", clip, sim::BuiltInClipNames());
      auto motion = std::make_shared<sim::Clip>(
          IsBuiltIn(sim::BuiltInClipNames(), clip)
              ? sim::MakeBuiltInClip(clip, sim::MakeHumanoidSkeleton())
              : assets::LoadClip(clip));
      render_once = [model, motion, size] {
        return render::RenderClipThumbnail(*model, *motion, size);
      };
    } else {
      kind = "garment";
      RequireBuiltInOrFile("--garment", garment, sim::BuiltInGarmentNames());
      const sim::SceneDescription scene = IsBuiltIn(sim::BuiltInGarmentNames(), garment)
                                              ? render::BuiltInGarmentScene(garment)
                                              : assets::LoadSceneFile(garment);
      render_once = [scene, size] { return render::RenderGarmentThumbnail(scene, size); };
    }
    std::vector<double> ms;
    render::Image image;
    for (int i = 0; i < runs; ++i) {
      const auto start = std::chrono::steady_clock::now();
      image = render_once();
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() -
                                                             start)
                       .count());
    }
    render::WritePng(out, image);
    std::sort(ms.begin(), ms.end());
    nlohmann::json report = {{"kind", kind},
                             {"size", size},
                             {"runs", runs},
                             {"median_ms", ms[ms.size() / 2]},
                             {"min_ms", ms.front()},
                             {"max_ms", ms.back()},
                             {"out", out}};
    std::cout << report.dump() << "\n";
  } catch (const sim::InputError& error) {
    std::cerr << "error: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
