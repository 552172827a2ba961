#include "render/image.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "sim_core/common/input_error.h"

namespace costume::render {
namespace {

Image RandomImage(int width, int height, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  Image image;
  image.width = width;
  image.height = height;
  image.rgba.resize(4u * width * height);
  for (std::uint8_t& value : image.rgba) value = static_cast<std::uint8_t>(byte(random));
  return image;
}

TEST(Png, RoundTripIsBitExact) {
  // Odd sizes and every byte value, alpha included (no premultiplication or gamma).
  for (const auto& [width, height] : {std::pair{1, 1}, {7, 3}, {64, 65}}) {
    const Image image = RandomImage(width, height, 17u * width + height);
    const Image decoded = DecodePng(EncodePng(image));
    EXPECT_EQ(decoded.width, width);
    EXPECT_EQ(decoded.height, height);
    EXPECT_EQ(decoded.rgba, image.rgba);
  }
}

TEST(Png, KeepsRowOrderTopFirst) {
  Image image;
  image.width = 1;
  image.height = 2;
  image.rgba = {255, 0, 0, 255, 0, 0, 255, 255};  // red above blue
  const std::vector<std::uint8_t> png = EncodePng(image);
  // The IHDR chunk starts at byte 8 (after the signature): width then height, big-endian.
  ASSERT_GT(png.size(), 24u);
  EXPECT_EQ(png[19], 1);
  EXPECT_EQ(png[23], 2);
  const Image decoded = DecodePng(png);
  EXPECT_EQ(decoded.Pixel(0, 0)[0], 255);
  EXPECT_EQ(decoded.Pixel(0, 1)[2], 255);
}

TEST(Png, WritePngWritesWhatEncodePngMakes) {
  const Image image = RandomImage(5, 4, 3);
  const std::string path =
      (std::filesystem::temp_directory_path() / "costume_render_image_test.png").string();
  WritePng(path, image);
  std::ifstream file(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                        std::istreambuf_iterator<char>());
  std::remove(path.c_str());
  EXPECT_EQ(bytes, EncodePng(image));
}

TEST(Png, RefusesBadData) {
  EXPECT_THROW(DecodePng({}), sim::InputError);
  EXPECT_THROW(DecodePng({'n', 'o', 't', ' ', 'a', ' ', 'p', 'n', 'g'}), sim::InputError);
  std::vector<std::uint8_t> truncated = EncodePng(RandomImage(32, 32, 5));
  truncated.resize(truncated.size() / 2);
  EXPECT_THROW(DecodePng(truncated), sim::InputError);
  std::vector<std::uint8_t> corrupt = EncodePng(RandomImage(32, 32, 6));
  for (std::size_t i = 60; i < corrupt.size() - 20; i += 7) corrupt[i] ^= 0x5a;
  EXPECT_THROW(DecodePng(corrupt), sim::InputError);
}

TEST(Png, RefusesMalformedImages) {
  Image image;
  EXPECT_THROW(EncodePng(image), sim::InputError);
  image.width = 2;
  image.height = 2;
  image.rgba.resize(15);
  EXPECT_THROW(EncodePng(image), sim::InputError);
}

/// The refusal names the file and the system's reason, which says what to fix.
void ExpectWriteRefused(const std::string& path, const std::string& reason) {
  try {
    WritePng(path, RandomImage(2, 2, 1));
    ADD_FAILURE() << path << " was written";
  } catch (const sim::InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(path + ": cannot write the PNG file"), std::string::npos) << message;
    EXPECT_NE(message.find(reason), std::string::npos) << message;
  }
}

TEST(Png, WritePngRefusesAMissingFolderAndAFolder) {
  ExpectWriteRefused("/nonexistent-folder/x.png", "No such file or directory");
  ExpectWriteRefused(std::filesystem::temp_directory_path().string(), "Is a directory");
}

}  // namespace
}  // namespace costume::render
