#pragma once
/// @file
/// An OSMesa offscreen OpenGL 3.3 core context rendering into memory: no display needed.

#include <cstdint>
#include <vector>

#include "render/gl_functions.h"
#include "render/image.h"

namespace costume::render {

/// An offscreen OpenGL 3.3 core context (OSMesa, Mesa's llvmpipe) with a width × height RGBA
/// colour buffer and a depth buffer. Made current on construction.
class OffscreenContext {
 public:
  /// Creates the context with OSMesaCreateContextAttribs (core profile 3.3) and makes it
  /// current. Throws sim::InputError for a size outside 1..8192 or when OSMesa refuses.
  OffscreenContext(int width, int height);
  ~OffscreenContext();
  OffscreenContext(const OffscreenContext&) = delete;
  OffscreenContext& operator=(const OffscreenContext&) = delete;

  /// The loader for this context's entry points (OSMesaGetProcAddress).
  GlLoader Loader() const;
  /// The colour buffer as an image, top row first (finishes pending GL work first).
  Image ReadPixels() const;
  /// Makes this context current on the calling thread.
  void MakeCurrent();

  int width() const { return width_; }
  int height() const { return height_; }

 private:
  void* context_ = nullptr;  // OSMesaContext, kept opaque so users need not include osmesa.h
  int width_ = 0;
  int height_ = 0;
  std::vector<std::uint8_t> buffer_;  // OSMesa's colour buffer, bottom row first
};

}  // namespace costume::render
