// Seeding with the OSMesa renderer: every built-in entry gets a PNG thumbnail showing its
// object (skin-coloured body; blue cloth on the garments), and a catalogue seeded without a
// renderer can fill its thumbnails in later. The renderer's own silhouette tests live with
// it (tests/render); here the pipeline from catalogue to PNG is checked.

#include "catalog/rendered_thumbnails.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "render/image.h"
#include "render/thumbnails.h"
#include "sim_core/avatar/procedural_humanoid.h"

namespace costume::catalog {
namespace {

struct Coverage {
  double object = 0.0;  // pixels unlike the background (the top-left corner) [fraction]
  double cloth = 0.0;   // clearly blue pixels: the cloth colour, not skin [fraction]
};

Coverage Measure(const render::Image& image) {
  const std::uint8_t* background = image.Pixel(0, 0);
  int object = 0, cloth = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const std::uint8_t* p = image.Pixel(x, y);
      int difference = 0;
      for (int c = 0; c < 3; ++c) difference += std::abs(p[c] - background[c]);
      if (difference > 30) ++object;
      if (difference > 30 && p[2] > p[0] + 30) ++cloth;
    }
  }
  const double n = image.width * image.height;
  return {object / n, cloth / n};
}

class RenderedThumbnailsTest : public testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/catalog-thumbs-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

TEST_F(RenderedThumbnailsTest, SeededEntriesShowTheirObject) {
  auto catalog = Catalog::Open("sqlite:" + dir_ + "/c.sqlite", WithRenderedThumbnails(64));
  for (Kind kind : {Kind::kAvatar, Kind::kAnimation, Kind::kGarment}) {
    for (const EntryInfo& entry : catalog->List(kind)) {
      SCOPED_TRACE(entry.name);
      const auto png = catalog->Thumbnail(entry.id);
      ASSERT_FALSE(png.empty());
      const render::Image image = render::DecodePng(png);
      EXPECT_EQ(image.width, 64);
      EXPECT_EQ(image.height, 64);
      const Coverage coverage = Measure(image);
      // A standing figure framed to fit covers a good part of the square, never all of it.
      EXPECT_GT(coverage.object, 0.05);
      EXPECT_LT(coverage.object, 0.8);
      if (kind == Kind::kGarment) {
        EXPECT_GT(coverage.cloth, 0.02);  // the garment is drawn on the body
      } else {
        EXPECT_LT(coverage.cloth, 0.005);  // a body alone has no cloth-blue pixels
      }
    }
  }
  // The stored avatar thumbnail is the renderer's image of the built-in humanoid.
  const auto humanoid = catalog->Find(Kind::kAvatar, "humanoid");
  const render::Image direct = render::RenderAvatarThumbnail(*sim::MakeHumanoid(), 64);
  EXPECT_EQ(render::DecodePng(catalog->Thumbnail(humanoid->id)).rgba, direct.rgba);
}

TEST_F(RenderedThumbnailsTest, MissingThumbnailsAreFilledInLater) {
  auto catalog = Catalog::Open("sqlite:" + dir_ + "/c.sqlite");  // seeded without renderer
  const auto walk = catalog->Find(Kind::kAnimation, "walk");
  EXPECT_TRUE(catalog->Thumbnail(walk->id).empty());
  EXPECT_EQ(catalog->FillMissingThumbnails(RenderedThumbnails(), 32), 10);
  EXPECT_EQ(render::DecodePng(catalog->Thumbnail(walk->id)).width, 32);
  EXPECT_EQ(catalog->FillMissingThumbnails(RenderedThumbnails(), 32), 0);  // none missing
}

}  // namespace
}  // namespace costume::catalog
