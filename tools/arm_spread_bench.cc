// How long the automatic arms' spread search takes (sim_core/scene/arm_spread.h), per avatar
// and clip: the simulation server and the GUI's mirror each run it when a scene is built or a
// posture set, in their loops, so its time is a stall of both. Prints one JSON object per
// case: the search's time the first time and the median and fastest over the repetitions
// (the first search on an avatar builds the body's trees, later ones copy them:
// sim_core/collision/mesh_distance.h), and what it chose.
//
//   build/tools/arm_spread_bench [--data ../shared/data] [--reps 5]

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "assets/scene_file.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/arm_spread.h"

namespace {

using costume::sim::ArmSpreadFit;
namespace fs = std::filesystem;

struct Case {
  std::string avatar;  ///< the scene's [avatar] lines naming the body
  std::string clip;    ///< a built-in clip's name or a clip file's path
};

/// The cases: the built-in humanoid with three built-in clips (none near: the search is a
/// pass over the clip) and, when the shared assets are there, it, MakeHuman's body and
/// Khronos' CesiumMan with CMU's walk and kick (whose retargeted forearms come near the
/// hips, so the search turns the arms).
std::vector<Case> Cases(const fs::path& data) {
  std::vector<Case> cases = {{"", "walk"}, {"", "kick"}, {"", "dance"}};
  const fs::path mh = data / "makehuman" / "body";
  const fs::path cesium = data / "khronos-cesiumman" / "CesiumMan.glb";
  const fs::path cmu = data / "cmu-mocap-bvh";
  if (!fs::exists(cmu / "02_02.bvh") || !fs::exists(cmu / "10_01.bvh")) {
    std::cerr << "arm_spread_bench: no CMU clips 02_02.bvh and 10_01.bvh in " << cmu
              << ": the built-in humanoid's clips only (--data names the shared assets)\n";
    return cases;
  }
  std::vector<std::string> bodies = {""};
  if (fs::exists(mh / "base.obj")) {
    bodies.push_back("model = \"" + fs::absolute(mh / "base.obj").string() + "\"\nskeleton = \"" +
                     fs::absolute(mh / "default.mhskel").string() + "\"\nweights = \"" +
                     fs::absolute(mh / "default_weights.mhw").string() + "\"\n");
  }
  if (fs::exists(cesium)) bodies.push_back("model = \"" + fs::absolute(cesium).string() + "\"\n");
  for (const std::string& body : bodies) {
    for (const char* clip : {"02_02.bvh", "10_01.bvh"}) {
      cases.push_back({body, fs::absolute(cmu / clip).string()});
    }
  }
  return cases;
}

/// Degrees to the hundredth (the search's steps are whole degrees).
double Degrees(double radians) { return std::round(radians * 180.0 / M_PI * 100.0) / 100.0; }

nlohmann::json Run(const Case& c, int reps) {
  // A scene needs a garment; the search does not look at it.
  const std::string text = "[avatar]\n" + c.avatar + "clip = \"" + c.clip +
                           "\"\n[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n";
  const costume::sim::SceneDescription scene =
      costume::assets::ParseSceneText(text, "arm_spread_bench.toml", "");
  const costume::sim::AvatarSpec& spec = *scene.avatar;
  std::vector<double> ms;
  ArmSpreadFit fit;
  for (int r = 0; r < reps; ++r) {
    const auto start = std::chrono::steady_clock::now();
    fit = costume::sim::FindArmSpread(spec.avatar, spec.clip, spec.motion);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() -
                                                           start)
                     .count());
  }
  const double first = ms.front();
  std::sort(ms.begin(), ms.end());
  return {{"avatar", spec.avatar->name()},
          {"vertices", spec.avatar->num_vertices()},
          {"triangles", spec.avatar->triangles().size()},
          {"clip", fs::path(c.clip).filename().string()},
          {"search_ms_first", first},
          {"search_ms_median", ms[ms.size() / 2]},
          {"search_ms_min", ms.front()},
          {"reps", reps},
          {"measured", fit.measured},
          {"frames_sampled", fit.frames_sampled},
          {"spread_degrees", {Degrees(fit.angle[0]), Degrees(fit.angle[1])}},
          {"frames_near_before", fit.frames_near_before},
          {"frames_near_after", fit.frames_near_after}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"arm_spread_bench: the automatic arms' spread search's time per avatar and clip "
               "(sim_core/scene/arm_spread.h)"};
  std::string data = "../shared/data";
  int reps = 5;
  app.add_option("--data", data, "Folder of the shared assets (MakeHuman, CesiumMan, CMU)")
      ->capture_default_str();
  app.add_option("--reps", reps, "Searches per case: the first, the median and the fastest are reported")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    for (const Case& c : Cases(data)) {
      std::cout << Run(c, reps).dump() << std::endl;
    }
  } catch (const costume::sim::InputError& error) {
    std::cerr << "arm_spread_bench: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
