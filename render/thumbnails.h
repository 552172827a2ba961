#pragma once
/// @file
/// Offscreen thumbnails of the catalogue's entries (issue 6): an avatar in its rest pose, an
/// animation's mid-clip pose, a garment draped on its avatar. Each renders in its own
/// OffscreenContext with the SceneRenderer, so no display is needed.

#include <string>

#include "render/camera.h"
#include "render/image.h"
#include "render/scene_renderer.h"
#include "sim_core/avatar/avatar.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/scene/scene_description.h"

namespace costume::render {

/// What a thumbnail shows and from where: the scene, the camera and the image size. The render
/// functions below are BuildXxx + RenderThumbnail; the Build functions let tests project the
/// same vertices with the same camera.
struct Thumbnail {
  RenderScene scene;
  Camera camera;
  int size = 0;  ///< width = height [px]
};

/// Renders `thumbnail` in a fresh size × size OffscreenContext.
Image RenderThumbnail(const Thumbnail& thumbnail);

/// `scene` framed as a garment thumbnail is (from the front right, or the back right when
/// its last mesh, the cloth, hangs behind its first, the avatar), no floor.
Thumbnail FrameGarmentScene(RenderScene scene, int size);

/// The avatar in its rest pose, seen from the front (+z towards the camera), skin coloured,
/// framed to fit `size` × `size` pixels. Throws sim::InputError for size outside 16..4096.
Thumbnail BuildAvatarThumbnail(const sim::Avatar& avatar, int size);
/// Renders BuildAvatarThumbnail.
Image RenderAvatarThumbnail(const sim::Avatar& avatar, int size);

/// The avatar posed at the middle of `clip` (clip retargeted onto the avatar's skeleton, the
/// arms spread as sim::FindArmSpread chooses for this avatar, as the simulation plays it), from
/// the front, framed like BuildAvatarThumbnail. Throws sim::InputError for an invalid clip or
/// one that cannot be retargeted onto the avatar.
Thumbnail BuildClipThumbnail(const sim::Avatar& avatar, const sim::Clip& clip, int size);
/// Renders BuildClipThumbnail.
Image RenderClipThumbnail(const sim::Avatar& avatar, const sim::Clip& clip, int size);

/// The garment(s) of `scene` on its avatar (rest pose), after a short fit so the cloth drapes,
/// from the front and slightly above. Throws sim::InputError when the scene does not build.
Thumbnail BuildGarmentThumbnail(const sim::SceneDescription& scene, int size);
/// Renders BuildGarmentThumbnail.
Image RenderGarmentThumbnail(const sim::SceneDescription& scene, int size);

/// A built-in garment pattern ("skirt", "cape", "dress", see sim::BuiltInGarmentNames) on the
/// built-in humanoid. Throws sim::InputError naming the allowed patterns for an unknown name.
Image RenderGarmentThumbnail(const std::string& pattern, int size);
/// The scene RenderGarmentThumbnail(pattern, size) renders.
sim::SceneDescription BuiltInGarmentScene(const std::string& pattern);

}  // namespace costume::render
