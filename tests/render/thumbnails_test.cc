#include "render/thumbnails.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <initializer_list>

#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/surface_geometry.h"
#include "sim_core/common/input_error.h"
#include "tests/support/humanoid.h"
#include "tests/render/coverage.h"

namespace costume::render {
namespace {

using testing::CoverageMask;
using testing::DiffersFrom;
using testing::Rasterise;

constexpr int kSize = 128;

// Checks a thumbnail's silhouette against its meshes projected by the thumbnail's own camera:
// (a) the pixel under every sampled vertex whose neighbourhood the projected triangles cover
// is drawn; (b) every pixel more than 2 pixels outside the projected bounding box is
// background; (c) pixels well inside / well outside the projected triangles (a 3×3
// neighbourhood all covered / all uncovered) are drawn / background.
void ExpectSilhouette(const Thumbnail& thumbnail, const Image& image) {
  ASSERT_EQ(image.width, thumbnail.size);
  ASSERT_EQ(image.height, thumbnail.size);
  const Eigen::Vector3f& background = thumbnail.scene.background;
  const int size = thumbnail.size;
  const CoverageMask mask = Rasterise(thumbnail.scene.meshes, thumbnail.camera, size, size);

  Eigen::AlignedBox2d bounds;
  int sampled = 0, drawn = 0;
  for (const DrawMesh& mesh : thumbnail.scene.meshes) {
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      const Eigen::Vector2d p =
          ProjectToPixel(thumbnail.camera, mesh.positions[i].cast<double>(), size, size).value();
      bounds.extend(p);
      const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
      if (i % 7 != 0 || !mask.All(x, y, 1, true)) continue;
      ++sampled;
      if (DiffersFrom(image, x, y, background)) ++drawn;
    }
  }
  EXPECT_GT(sampled, 50);
  EXPECT_EQ(drawn, sampled);
  // Framed: the object fills most of the image's height, inside its borders.
  EXPECT_GT(bounds.sizes().maxCoeff(), 0.6 * size);
  EXPECT_GE(bounds.min().minCoeff(), 0.0);
  EXPECT_LE(bounds.max().maxCoeff(), size);

  int margin_pixels = 0, margin_drawn = 0, inside = 0, inside_wrong = 0, outside = 0,
      outside_wrong = 0;
  const Eigen::AlignedBox2d widened(bounds.min() - Eigen::Vector2d::Constant(2.0),
                                    bounds.max() + Eigen::Vector2d::Constant(2.0));
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const bool differs = DiffersFrom(image, x, y, background);
      if (!widened.contains(Eigen::Vector2d(x + 0.5, y + 0.5))) {
        ++margin_pixels;
        margin_drawn += differs;
      }
      if (mask.All(x, y, 1, true)) {
        ++inside;
        inside_wrong += !differs;
      } else if (mask.All(x, y, 1, false)) {
        ++outside;
        outside_wrong += differs;
      }
    }
  }
  EXPECT_GT(margin_pixels, size * size / 4);
  EXPECT_EQ(margin_drawn, 0);
  EXPECT_GT(inside, 300);
  EXPECT_EQ(inside_wrong, 0);
  EXPECT_EQ(outside_wrong, 0);
}

TEST(Thumbnails, AvatarAtRestShowsItsSilhouette) {
  const auto avatar = sim::MakeHumanoid();
  const Thumbnail thumbnail = BuildAvatarThumbnail(*avatar, kSize);
  ASSERT_EQ(thumbnail.scene.meshes.size(), 1u);
  EXPECT_EQ(thumbnail.scene.meshes[0].positions.size(),
            static_cast<std::size_t>(avatar->num_vertices()));
  ExpectSilhouette(thumbnail, RenderThumbnail(thumbnail));
  // The one-call form renders the same image.
  EXPECT_EQ(RenderAvatarThumbnail(*avatar, kSize).rgba, RenderThumbnail(thumbnail).rgba);
}

TEST(Thumbnails, ClipShowsTheMidClipPose) {
  const auto avatar = sim::MakeHumanoid();
  const sim::Clip walk = sim::MakeBuiltInClip("walk", sim::MakeHumanoidSkeleton());
  const Thumbnail thumbnail = BuildClipThumbnail(*avatar, walk, kSize);
  ExpectSilhouette(thumbnail, RenderThumbnail(thumbnail));
}

// A clip holding the left arm 24° in puts the hand into the thigh (tests/support/humanoid.h);
// the simulation plays it with the arm spread out, and the thumbnail shows that: before, it
// drew the hand through the thigh.
TEST(Thumbnails, ClipShowsTheArmsSpreadAsTheSimulationPlaysThem) {
  const auto avatar = test::Humanoid();
  const auto& segments = avatar->vertex_segments();
  const auto in = [&](int v, std::initializer_list<sim::HAnimJoint> joints) {
    return segments[v] && std::find(joints.begin(), joints.end(), *segments[v]) != joints.end();
  };
  const Thumbnail thumbnail = BuildClipThumbnail(*avatar, *test::ArmInClip(24.0), kSize);
  const std::vector<Eigen::Vector3f>& posed = thumbnail.scene.meshes.at(0).positions;
  sim::Points x(static_cast<Eigen::Index>(posed.size()), 3);
  for (std::size_t v = 0; v < posed.size(); ++v) {
    x.row(static_cast<Eigen::Index>(v)) = posed[v].cast<double>();
  }
  // The pelvis and legs, as posed: the built-in humanoid's closed tubes (connected pieces)
  // whose first corner's segment is one of theirs.
  using J = sim::HAnimJoint;
  const std::initializer_list<J> legs = {J::kSacroiliac, J::kLHip, J::kRHip, J::kLKnee,
                                         J::kRKnee, J::kLTalocrural, J::kRTalocrural};
  const sim::SurfacePseudonormals surface(avatar->num_vertices(), avatar->triangles());
  std::vector<char> leg_piece(surface.num_pieces(), 0);
  for (int t = 0; t < surface.num_triangles(); ++t) {
    if (in(avatar->triangles()[t][0], legs)) leg_piece[surface.piece_of(t)] = 1;
  }
  std::vector<Eigen::Vector3i> lower;
  for (int t = 0; t < surface.num_triangles(); ++t) {
    if (leg_piece[surface.piece_of(t)]) lower.push_back(avatar->triangles()[t]);
  }
  const sim::MeshDistance body("lower body", x, lower);
  int hand_inside = 0, hand = 0;
  for (int v = 0; v < avatar->num_vertices(); ++v) {
    if (!in(v, {J::kLElbow, J::kLRadiocarpal})) continue;
    ++hand;
    hand_inside += body.Inside(x.row(v).transpose());
  }
  ASSERT_GT(hand, 50);
  EXPECT_EQ(hand_inside, 0) << "of " << hand << " forearm and hand vertices";
}

TEST(Thumbnails, PosedSilhouetteDiffersFromRestWhereTheLimbsMoved) {
  // Rest and mid-walk drawn with one camera: pixels the posed body covers well inside and
  // the rest body leaves well outside (the swung leg, the arms) must be drawn in the clip's
  // thumbnail and background in the rest one, and the other way round.
  const auto avatar = sim::MakeHumanoid();
  const sim::Clip walk = sim::MakeBuiltInClip("walk", sim::MakeHumanoidSkeleton());
  Thumbnail rest = BuildAvatarThumbnail(*avatar, kSize);
  Thumbnail posed = BuildClipThumbnail(*avatar, walk, kSize);
  Eigen::AlignedBox3d both;
  for (const Thumbnail* t : {&rest, &posed}) {
    for (const Eigen::Vector3f& p : t->scene.meshes[0].positions) both.extend(p.cast<double>());
  }
  const Camera camera = FrameBox(both, Eigen::Vector3d(-1.0, -0.1, -0.4));  // from the side
  rest.camera = camera;
  posed.camera = camera;
  const Image rest_image = RenderThumbnail(rest);
  const Image posed_image = RenderThumbnail(posed);
  const CoverageMask rest_mask = Rasterise(rest.scene.meshes, camera, kSize, kSize);
  const CoverageMask posed_mask = Rasterise(posed.scene.meshes, camera, kSize, kSize);
  const Eigen::Vector3f& background = rest.scene.background;
  int only_posed = 0, only_rest = 0, wrong = 0;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      if (posed_mask.All(x, y, 1, true) && rest_mask.All(x, y, 1, false)) {
        ++only_posed;
        wrong += !DiffersFrom(posed_image, x, y, background) ||
                 DiffersFrom(rest_image, x, y, background);
      } else if (rest_mask.All(x, y, 1, true) && posed_mask.All(x, y, 1, false)) {
        ++only_rest;
        wrong += !DiffersFrom(rest_image, x, y, background) ||
                 DiffersFrom(posed_image, x, y, background);
      }
    }
  }
  EXPECT_GT(only_posed, 40);
  EXPECT_GT(only_rest, 40);
  EXPECT_EQ(wrong, 0);
}

TEST(Thumbnails, GarmentOnTheBuiltInHumanoid) {
  const Thumbnail thumbnail = BuildGarmentThumbnail(BuiltInGarmentScene("skirt"), kSize);
  ASSERT_EQ(thumbnail.scene.meshes.size(), 2u);  // avatar, then cloth
  EXPECT_TRUE(thumbnail.scene.meshes[1].two_sided);
  const Image image = RenderThumbnail(thumbnail);
  ExpectSilhouette(thumbnail, image);
  // The cloth shows in its own colour: the pixel under the skirt's front hem is bluish.
  const DrawMesh& cloth = thumbnail.scene.meshes[1];
  const CoverageMask avatar_mask = Rasterise({thumbnail.scene.meshes[0]}, thumbnail.camera,
                                             kSize, kSize);
  const CoverageMask cloth_mask = Rasterise({cloth}, thumbnail.camera, kSize, kSize);
  int cloth_only = 0, blue = 0;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      if (!cloth_mask.All(x, y, 1, true) || !avatar_mask.All(x, y, 2, false)) continue;
      ++cloth_only;
      const std::uint8_t* p = image.Pixel(x, y);
      blue += p[2] > p[0] + 30;
    }
  }
  EXPECT_GT(cloth_only, 100);
  EXPECT_EQ(blue, cloth_only);
}

TEST(Thumbnails, RefuseBadInput) {
  const auto avatar = sim::MakeHumanoid();
  EXPECT_THROW(RenderAvatarThumbnail(*avatar, 8), sim::InputError);
  EXPECT_THROW(RenderGarmentThumbnail("trousers", 64), sim::InputError);
  sim::Clip empty;
  empty.skeleton = sim::MakeHumanoidSkeleton();
  EXPECT_THROW(RenderClipThumbnail(*avatar, empty, 64), sim::InputError);
}

}  // namespace
}  // namespace costume::render
