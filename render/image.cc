#include "render/image.h"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>

#include "sim_core/common/input_error.h"

namespace costume::render {
namespace {

void CheckImage(const Image& image, const std::string& context) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgba.size() != 4u * static_cast<std::size_t>(image.width) * image.height) {
    throw sim::InputError(context + ": image of " + std::to_string(image.width) + " x " +
                          std::to_string(image.height) + " pixels with " +
                          std::to_string(image.rgba.size()) +
                          " bytes: need width, height > 0 and 4 bytes per pixel");
  }
}

// libpng's simplified API (1.6): it reports errors through png_image::message instead of
// longjmp, so no C++ object is ever jumped over.
png_image DescribeRgba(const Image& image) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGBA;
  return png;
}

}  // namespace

std::vector<std::uint8_t> EncodePng(const Image& image) {
  CheckImage(image, "EncodePng");
  png_image png = DescribeRgba(image);
  png_alloc_size_t size = 0;
  if (!png_image_write_to_memory(&png, nullptr, &size, 0, image.rgba.data(), 0, nullptr)) {
    throw sim::InputError(std::string("EncodePng: ") + png.message);
  }
  std::vector<std::uint8_t> bytes(size);
  if (!png_image_write_to_memory(&png, bytes.data(), &size, 0, image.rgba.data(), 0, nullptr)) {
    throw sim::InputError(std::string("EncodePng: ") + png.message);
  }
  bytes.resize(size);
  return bytes;
}

void WritePng(const std::string& path, const Image& image) {
  const std::vector<std::uint8_t> bytes = EncodePng(image);
  std::ofstream file(path, std::ios::binary);
  // The system's reason (no such folder, a folder, no permission) tells the user what to fix.
  if (!file) throw sim::InputError(path + ": cannot write the PNG file: " + std::strerror(errno));
  file.write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  file.close();
  if (!file) throw sim::InputError(path + ": cannot write the PNG file: " + std::strerror(errno));
}

Image DecodePng(const std::vector<std::uint8_t>& bytes) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&png, bytes.data(), bytes.size())) {
    throw sim::InputError(std::string("DecodePng: not a valid PNG (") + png.message + ")");
  }
  png.format = PNG_FORMAT_RGBA;
  Image image;
  image.width = static_cast<int>(png.width);
  image.height = static_cast<int>(png.height);
  image.rgba.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, image.rgba.data(), 0, nullptr)) {
    png_image_free(&png);
    throw sim::InputError(std::string("DecodePng: corrupt PNG data (") + png.message + ")");
  }
  return image;
}

}  // namespace costume::render
