#include "catalog/rendered_thumbnails.h"

#include "render/image.h"
#include "render/thumbnails.h"
#include "sim_core/common/input_error.h"

namespace costume::catalog {

ThumbnailMaker RenderedThumbnails() {
  return [](const ThumbnailRequest& request) -> std::vector<std::uint8_t> {
    switch (request.kind) {
      case Kind::kAvatar:
        if (!request.avatar) break;
        return render::EncodePng(render::RenderAvatarThumbnail(*request.avatar, request.size));
      case Kind::kAnimation:
        if (!request.avatar || !request.clip) break;
        return render::EncodePng(
            render::RenderClipThumbnail(*request.avatar, *request.clip, request.size));
      case Kind::kGarment:
        if (!request.pattern.empty()) {
          return render::EncodePng(render::RenderGarmentThumbnail(request.pattern, request.size));
        }
        if (!request.garment_scene) break;
        return render::EncodePng(
            render::RenderGarmentThumbnail(*request.garment_scene, request.size));
    }
    throw sim::InputError(std::string("thumbnail of ") + KindName(request.kind) + " '" +
                          request.name + "': the request lacks what to draw");
  };
}

OpenOptions WithRenderedThumbnails(int size) {
  OpenOptions options;
  options.thumbnails = RenderedThumbnails();
  options.thumbnail_size = size;
  return options;
}

}  // namespace costume::catalog
