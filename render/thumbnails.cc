#include "render/thumbnails.h"

#include <algorithm>

#include "render/offscreen_context.h"
#include "render/scene_meshes.h"
#include "sim_core/avatar/avatar_motion.h"
#include "sim_core/avatar/garment_patterns.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/arm_spread.h"
#include "sim_core/scene/simulation.h"

namespace costume::render {
namespace {

// Thumbnails are rendered this many times larger and box-filtered down: OSMesa's default
// framebuffer has no multisampling, and jagged edges look poor in a list of small images.
constexpr int kSupersampling = 2;
// Avatars are seen from the front (they face +z), a little from above; poses and garments
// from the front right, where a stride or a drape reads better.
const Eigen::Vector3d kFrontView(0.0, -0.15, -1.0);
const Eigen::Vector3d kThreeQuarterView(-0.6, -0.2, -1.0);
// Simulated fit of garment thumbnails [s]: the cloth falls and settles enough to show its
// shape (tools/render_thumbnail reports the time this takes).
constexpr double kGarmentFitTime = 0.5;

void CheckSize(int size) {
  if (size < 16 || size > 4096) {
    throw sim::InputError("thumbnail size = " + std::to_string(size) +
                          ": allowed range 16..4096 pixels");
  }
}

Eigen::AlignedBox3d BoundsOf(const RenderScene& scene) {
  Eigen::AlignedBox3d box;
  for (const DrawMesh& mesh : scene.meshes) {
    for (const Eigen::Vector3f& p : mesh.positions) box.extend(p.cast<double>());
  }
  return box;
}

// A thumbnail of the meshes, framed from the front; no floor, so the silhouette stands out.
Thumbnail Frame(RenderScene scene, const Eigen::Vector3d& view_direction, int size) {
  Thumbnail thumbnail;
  scene.floor = false;
  thumbnail.camera = FrameBox(BoundsOf(scene), view_direction);
  thumbnail.scene = std::move(scene);
  thumbnail.size = size;
  return thumbnail;
}

// Averages each factor × factor block of `large` into one pixel.
Image Downsample(const Image& large, int factor) {
  Image small;
  small.width = large.width / factor;
  small.height = large.height / factor;
  small.rgba.resize(4u * small.width * small.height);
  const int count = factor * factor;
  for (int y = 0; y < small.height; ++y) {
    for (int x = 0; x < small.width; ++x) {
      for (int c = 0; c < 4; ++c) {
        int sum = 0;
        for (int dy = 0; dy < factor; ++dy) {
          for (int dx = 0; dx < factor; ++dx) {
            sum += large.Pixel(factor * x + dx, factor * y + dy)[c];
          }
        }
        small.rgba[4 * (y * small.width + x) + c] =
            static_cast<std::uint8_t>((sum + count / 2) / count);
      }
    }
  }
  return small;
}

// The three-quarter view from the front, or from the back when the cloth hangs mostly behind
// the avatar (a cape): its centroid lies further back (-z) than the body's by over 2 cm.
Eigen::Vector3d GarmentView(const RenderScene& scene) {
  if (scene.meshes.size() < 2) return kThreeQuarterView;
  const auto mean_z = [](const DrawMesh& mesh) {
    double sum = 0.0;
    for (const Eigen::Vector3f& p : mesh.positions) sum += p.z();
    return mesh.positions.empty() ? 0.0 : sum / mesh.positions.size();
  };
  const bool behind = mean_z(scene.meshes.back()) < mean_z(scene.meshes.front()) - 0.02;
  return behind ? Eigen::Vector3d(kThreeQuarterView.x(), kThreeQuarterView.y(),
                                  -kThreeQuarterView.z())
                : kThreeQuarterView;
}

// A shared_ptr that does not own: sim_core's motion classes take shared pointers, the
// thumbnail functions take references whose owner outlives the call.
template <typename T>
std::shared_ptr<const T> Borrow(const T& object) {
  return std::shared_ptr<const T>(std::shared_ptr<const T>(), &object);
}

}  // namespace

Image RenderThumbnail(const Thumbnail& thumbnail) {
  CheckSize(thumbnail.size);
  const int large = kSupersampling * thumbnail.size;
  OffscreenContext context(large, large);
  SceneRenderer renderer(context.Loader());
  renderer.Draw(thumbnail.scene, thumbnail.camera, large, large);
  return Downsample(context.ReadPixels(), kSupersampling);
}

Thumbnail FrameGarmentScene(RenderScene scene, int size) {
  CheckSize(size);
  const Eigen::Vector3d view = GarmentView(scene);
  return Frame(std::move(scene), view, size);
}

Thumbnail BuildAvatarThumbnail(const sim::Avatar& avatar, int size) {
  CheckSize(size);
  RenderScene scene;
  scene.meshes.push_back(
      ToDrawMesh(avatar.rest_vertices(), avatar.triangles(), kSkinColour, false));
  return Frame(std::move(scene), kFrontView, size);
}

Image RenderAvatarThumbnail(const sim::Avatar& avatar, int size) {
  return RenderThumbnail(BuildAvatarThumbnail(avatar, size));
}

Thumbnail BuildClipThumbnail(const sim::Avatar& avatar, const sim::Clip& clip, int size) {
  CheckSize(size);
  sim::ValidateClip(clip);
  // No fitting and no blend: Evaluate(t) is the clip's pose at t retargeted onto the avatar.
  sim::AvatarMotionSettings settings;
  settings.fit_time = 0.0;
  settings.blend_time = 0.0;
  // With the arms' spread the simulation chooses on this avatar (sim_core/scene/arm_spread.h):
  // a clip captured on a body narrower at the hips showed its hands through them.
  settings.arm_spread = sim::FindArmSpread(Borrow(avatar), Borrow(clip), settings).angle;
  sim::AvatarMotion motion(Borrow(avatar), Borrow(clip), settings);
  motion.Evaluate(0.5 * clip.duration());
  RenderScene scene;
  scene.meshes.push_back(ToDrawMesh(motion.vertices(), avatar.triangles(), kSkinColour, false));
  return Frame(std::move(scene), kThreeQuarterView, size);
}

Image RenderClipThumbnail(const sim::Avatar& avatar, const sim::Clip& clip, int size) {
  return RenderThumbnail(BuildClipThumbnail(avatar, clip, size));
}

Thumbnail BuildGarmentThumbnail(const sim::SceneDescription& scene, int size) {
  CheckSize(size);
  // The garment on the standing avatar: the clip would start after the fit, so drop it.
  sim::SceneDescription fit = scene;
  if (fit.avatar) {
    fit.avatar->clip = nullptr;
    fit.avatar->motion.fit_time = std::min(fit.avatar->motion.fit_time, kGarmentFitTime);
  }
  std::unique_ptr<sim::Simulation> simulation = sim::Simulation::Build(fit);
  const int frames = static_cast<int>(kGarmentFitTime * fit.frame_rate + 0.5);
  for (int i = 0; i < frames; ++i) simulation->AdvanceFrame();

  RenderScene render_scene;
  if (const sim::AvatarMotion* avatar = simulation->avatar()) {
    render_scene.meshes.push_back(ToDrawMesh(avatar->vertices(), avatar->avatar().triangles(),
                                               kSkinColour, false));
  }
  render_scene.meshes.push_back(ToDrawMesh(simulation->state().positions,
                                             simulation->model().triangles(), kClothColour, true));
  return FrameGarmentScene(std::move(render_scene), size);
}

Image RenderGarmentThumbnail(const sim::SceneDescription& scene, int size) {
  return RenderThumbnail(BuildGarmentThumbnail(scene, size));
}

sim::SceneDescription BuiltInGarmentScene(const std::string& pattern) {
  const std::vector<std::string>& names = sim::BuiltInGarmentNames();
  if (std::find(names.begin(), names.end(), pattern) == names.end()) {
    std::string allowed;
    for (const std::string& name : names) allowed += (allowed.empty() ? "" : ", ") + name;
    throw sim::InputError("garment pattern = '" + pattern + "': allowed " + allowed);
  }
  // The garment scene of scenes/garment.toml (its cotton), standing still.
  sim::SceneDescription scene;
  scene.name = pattern + "_thumbnail";
  scene.duration = kGarmentFitTime;
  sim::GarmentSpec garment;
  garment.name = pattern;
  garment.material = "cotton";
  garment.pattern = pattern;
  garment.pattern_resolution = 64;
  scene.garments.push_back(garment);
  sim::AvatarSpec avatar;
  avatar.avatar = sim::MakeHumanoid();
  // The skinned mesh: the superquadrics let the dress's bodice slip (seen in its thumbnail).
  avatar.collision = sim::BodyCollisionMethod::kMesh;
  avatar.motion.fit_time = kGarmentFitTime;
  scene.avatar = avatar;
  return scene;
}

Image RenderGarmentThumbnail(const std::string& pattern, int size) {
  return RenderGarmentThumbnail(BuiltInGarmentScene(pattern), size);
}

}  // namespace costume::render
