#include "render/offscreen_context.h"

#include "render/gl_functions.h"

// osmesa.h pulls in the legacy <GL/gl.h>; the renderer's own GL types come from glcorearb.h
// through gl_functions.h, included first so its PFN typedefs are complete.
#include <GL/osmesa.h>

#include <algorithm>
#include <cstring>
#include <string>

#include "sim_core/common/input_error.h"

namespace costume::render {
namespace {

constexpr int kMaxSize = 8192;

OSMesaContext Handle(void* context) { return static_cast<OSMesaContext>(context); }

}  // namespace

OffscreenContext::OffscreenContext(int width, int height) : width_(width), height_(height) {
  if (width < 1 || width > kMaxSize || height < 1 || height > kMaxSize) {
    throw sim::InputError("OffscreenContext: size = " + std::to_string(width) + " x " +
                          std::to_string(height) + ": allowed range 1..8192 per side");
  }
  const int attributes[] = {OSMESA_FORMAT,        OSMESA_RGBA,
                            OSMESA_DEPTH_BITS,    24,
                            OSMESA_PROFILE,       OSMESA_CORE_PROFILE,
                            OSMESA_CONTEXT_MAJOR_VERSION, 3,
                            OSMESA_CONTEXT_MINOR_VERSION, 3,
                            0};
  context_ = OSMesaCreateContextAttribs(attributes, nullptr);
  if (context_ == nullptr) {
    throw sim::InputError(
        "OffscreenContext: OSMesaCreateContextAttribs refused an OpenGL 3.3 core context "
        "(needs Mesa's OSMesa with llvmpipe, package libosmesa6)");
  }
  buffer_.assign(4u * static_cast<std::size_t>(width) * height, 0);
  MakeCurrent();
}

OffscreenContext::~OffscreenContext() {
  if (context_ != nullptr) OSMesaDestroyContext(Handle(context_));
}

void OffscreenContext::MakeCurrent() {
  if (!OSMesaMakeCurrent(Handle(context_), buffer_.data(), GL_UNSIGNED_BYTE, width_, height_)) {
    throw sim::InputError("OffscreenContext: OSMesaMakeCurrent failed for " +
                          std::to_string(width_) + " x " + std::to_string(height_));
  }
}

GlLoader OffscreenContext::Loader() const {
  return [](const char* name) -> void* {
    return reinterpret_cast<void*>(OSMesaGetProcAddress(name));
  };
}

Image OffscreenContext::ReadPixels() const {
  // Pending commands may still be in flight: the buffer is complete only after glFinish.
  auto finish = reinterpret_cast<PFNGLFINISHPROC>(OSMesaGetProcAddress("glFinish"));
  if (finish != nullptr) finish();
  Image image;
  image.width = width_;
  image.height = height_;
  image.rgba.resize(buffer_.size());
  const std::size_t row = 4u * static_cast<std::size_t>(width_);
  // OSMesa stores the bottom row first (OSMESA_Y_UP); images are top row first.
  for (int y = 0; y < height_; ++y) {
    std::memcpy(image.rgba.data() + y * row, buffer_.data() + (height_ - 1 - y) * row, row);
  }
  return image;
}

}  // namespace costume::render
