#pragma once
/// @file
/// The ThumbnailMaker that renders with the OSMesa renderer (render/thumbnails.h): avatars in
/// their rest pose, animations mid-clip on the built-in humanoid, garments draped on it. A
/// separate library (costume::catalog_thumbnails) so that the catalogue itself does not
/// depend on the renderer.

#include "catalog/catalog.h"

namespace costume::catalog {

/// Renders a request offscreen and encodes it as PNG. The maker throws sim::InputError when
/// the object cannot be drawn (the callers then store the entry without a thumbnail).
ThumbnailMaker RenderedThumbnails();

/// OpenOptions that seed with rendered thumbnails of `size` pixels.
OpenOptions WithRenderedThumbnails(int size = 128);

}  // namespace costume::catalog
