#pragma once
/// @file
/// A contact sheet: several moments of a run side by side in one image, so a person can see
/// at a glance whether a garment moves like cloth (tools/garment_bench writes one per case).

#include <vector>

#include "render/image.h"
#include "render/scene_renderer.h"
#include "sim_core/cloth/cloth_model.h"

namespace costume::render {

/// One moment: the avatar's skin and the cloth where they were [m].
struct SheetFrame {
  sim::Points avatar_vertices;
  std::vector<Eigen::Vector3i> avatar_triangles;
  sim::Points cloth_positions;
  std::vector<Eigen::Vector3i> cloth_triangles;
};

/// The frames as tiles of `tile` × `tile` pixels, `columns` to a row (left to right, top to
/// bottom), each framed on its own avatar and cloth from the front right (from the back
/// right when the cloth hangs behind the body, a cape), skin and cloth coloured as in the
/// thumbnails. Throws sim::InputError for no frames, a tile outside 16..1024 or columns < 1.
Image RenderContactSheet(const std::vector<SheetFrame>& frames, int tile, int columns);

}  // namespace costume::render
