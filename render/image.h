#pragma once
/// @file
/// An 8-bit RGBA image and its PNG encoding (libpng).

#include <cstdint>
#include <string>
#include <vector>

namespace costume::render {

/// An 8-bit RGBA image, rows stored top row first, 4 bytes per pixel, no row padding:
/// rgba.size() == 4 * width * height.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;  ///< top row first, R, G, B, A per pixel

  /// The pixel at column x (from the left) and row y (from the top); no bounds check.
  const std::uint8_t* Pixel(int x, int y) const { return rgba.data() + 4 * (y * width + x); }
};

/// Encodes `image` as an 8-bit RGBA PNG file in memory. Throws sim::InputError when the image
/// is empty or its buffer size does not match width × height × 4.
std::vector<std::uint8_t> EncodePng(const Image& image);

/// Writes `image` as a PNG file at `path`. Throws sim::InputError when the file cannot be written
/// (naming the path) or the image is malformed.
void WritePng(const std::string& path, const Image& image);

/// Decodes a PNG file held in memory into RGBA (any PNG colour type and bit depth is converted
/// to 8-bit RGBA). Throws sim::InputError for data that is not a valid PNG.
Image DecodePng(const std::vector<std::uint8_t>& png);

}  // namespace costume::render
