#include "render/contact_sheet.h"

#include <algorithm>
#include <string>

#include "render/scene_meshes.h"
#include "render/thumbnails.h"
#include "sim_core/common/input_error.h"

namespace costume::render {

Image RenderContactSheet(const std::vector<SheetFrame>& frames, int tile, int columns) {
  if (frames.empty()) throw sim::InputError("contact sheet: no frames to draw");
  if (tile < 16 || tile > 1024) {
    throw sim::InputError("contact sheet: tile = " + std::to_string(tile) +
                          " px: allowed range 16..1024");
  }
  if (columns < 1) {
    throw sim::InputError("contact sheet: columns = " + std::to_string(columns) +
                          ": allowed 1 or more");
  }
  const int count = static_cast<int>(frames.size());
  const int used_columns = std::min(columns, count);
  const int rows = (count + used_columns - 1) / used_columns;
  Image sheet;
  sheet.width = used_columns * tile;
  sheet.height = rows * tile;
  sheet.rgba.assign(4u * sheet.width * sheet.height, 255);
  for (int f = 0; f < count; ++f) {
    const SheetFrame& frame = frames[f];
    RenderScene scene;
    if (frame.avatar_vertices.rows() > 0) {
      scene.meshes.push_back(
          ToDrawMesh(frame.avatar_vertices, frame.avatar_triangles, kSkinColour, false));
    }
    scene.meshes.push_back(
        ToDrawMesh(frame.cloth_positions, frame.cloth_triangles, kClothColour, true));
    const Image image = RenderThumbnail(FrameGarmentScene(std::move(scene), tile));
    const int x0 = (f % used_columns) * tile, y0 = (f / used_columns) * tile;
    for (int y = 0; y < tile; ++y) {
      std::copy_n(image.Pixel(0, y), 4 * tile,
                  sheet.rgba.begin() + 4 * ((y0 + y) * sheet.width + x0));
    }
  }
  return sheet;
}

}  // namespace costume::render
