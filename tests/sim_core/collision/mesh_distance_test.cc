// Signed distance to closed meshes against closed forms: a tessellated box (exact), a
// sphere (within the tessellation error computed here), signs at the box's edges and
// corners, refitting after motion, bodies of several pieces, penetration statistics.
#include "sim_core/collision/mesh_distance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim_core/common/input_error.h"
#include "tests/sim_core/collision/test_meshes.h"

namespace costume::sim {
namespace {

using test::BoxSignedDistance;
using test::TessellatedBox;

const Eigen::Vector3d kCenter(0.1, -0.2, 0.3);
const Eigen::Vector3d kHalf(0.3, 0.2, 0.25);

Eigen::Vector3d RandomPoint(std::mt19937& rng, const Eigen::Vector3d& center, double extent) {
  std::uniform_real_distribution<double> uniform(-extent, extent);
  return center + Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
}

TEST(MeshDistance, MatchesTheBoxClosedFormEverywhere) {
  const auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  const MeshDistance distance("box", box.vertices, box.triangles);
  std::mt19937 rng(7);
  int num_inside = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, kCenter, 0.6);
    const double expected = BoxSignedDistance(p, kCenter, kHalf);
    num_inside += expected < 0.0;
    ASSERT_NEAR(distance.SignedDistance(p, 2.0), expected, 1e-12) << p.transpose();
  }
  EXPECT_GT(num_inside, 100);  // both signs were exercised
}

TEST(MeshDistance, SignIsRightAtEdgesAndCorners) {
  const auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  const MeshDistance distance("box", box.vertices, box.triangles);
  // Corners (all of ±1) and edge midpoints (one coordinate 0), offset by small steps in
  // every direction around them: where a single face normal gives the wrong sign.
  const double steps[] = {-1.0, -0.5, 0.0, 0.5, 1.0};
  int num_checked = 0;
  for (int sx = -1; sx <= 1; ++sx) {
    for (int sy = -1; sy <= 1; ++sy) {
      for (int sz = -1; sz <= 1; ++sz) {
        const int num_zero = (sx == 0) + (sy == 0) + (sz == 0);
        if (num_zero > 1) continue;  // face centres are no edge or corner
        const Eigen::Vector3d feature =
            kCenter + kHalf.cwiseProduct(Eigen::Vector3d(sx, sy, sz));
        for (double a : steps) {
          for (double b : steps) {
            for (double c : steps) {
              const Eigen::Vector3d p = feature + 1e-3 * Eigen::Vector3d(a, b, c);
              const double expected = BoxSignedDistance(p, kCenter, kHalf);
              if (std::abs(expected) < 1e-9) continue;  // on the surface: no sign to check
              const double got = distance.SignedDistance(p, 0.1);
              ASSERT_EQ(got < 0.0, expected < 0.0) << p.transpose();
              ASSERT_NEAR(got, expected, 1e-12);
              ++num_checked;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(num_checked, 2000);
}

TEST(MeshDistance, QueryGivesClosestPointAndOutwardNormal) {
  const auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  const MeshDistance distance("box", box.vertices, box.triangles);
  // 5 cm above the top face, off its grid lines.
  const Eigen::Vector3d top = kCenter + Eigen::Vector3d(0.013, kHalf.y(), -0.021);
  const SurfaceDistance above = distance.Query(top + Eigen::Vector3d(0, 0.05, 0), 1.0);
  EXPECT_NEAR(above.signed_distance, 0.05, 1e-12);
  EXPECT_LT((above.closest_point - top).norm(), 1e-12);
  EXPECT_LT((above.normal - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  // 2 cm below it, inside: the normal still points out.
  const SurfaceDistance below = distance.Query(top - Eigen::Vector3d(0, 0.02, 0), 1.0);
  EXPECT_NEAR(below.signed_distance, -0.02, 1e-12);
  EXPECT_LT((below.normal - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  // Beyond the search radius: +inf, whichever side.
  EXPECT_EQ(distance.SignedDistance(top + Eigen::Vector3d(0, 0.05, 0), 0.04),
            std::numeric_limits<double>::infinity());
  EXPECT_EQ(distance.SignedDistance(kCenter, 0.1), std::numeric_limits<double>::infinity());
}

TEST(MeshDistance, MatchesTheSphereWithinTheTessellationError) {
  const Eigen::Vector3d center(0.0, 1.0, 0.0);
  const double radius = 0.5;
  const auto sphere = test::CubeSphere(center, radius, 8);
  // The mesh lies between the radius and the smallest distance from the centre to a
  // triangle's plane, which bounds the distance error at any point.
  double min_plane = radius;
  for (const Eigen::Vector3i& t : sphere.triangles) {
    const Eigen::Vector3d a = sphere.vertices.row(t[0]).transpose() - center;
    const Eigen::Vector3d b = sphere.vertices.row(t[1]).transpose() - center;
    const Eigen::Vector3d c = sphere.vertices.row(t[2]).transpose() - center;
    min_plane = std::min(min_plane, std::abs((b - a).cross(c - a).normalized().dot(a)));
  }
  const double tessellation_error = radius - min_plane;
  ASSERT_GT(tessellation_error, 0.0);
  ASSERT_LT(tessellation_error, 0.02);
  const MeshDistance distance("sphere", sphere.vertices, sphere.triangles);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> radial(0.1, 0.9);
  std::normal_distribution<double> gauss;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d direction =
        Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const double r = radial(rng);
    const double got = distance.SignedDistance(center + r * direction, 1.0);
    ASSERT_NEAR(got, r - radius, tessellation_error + 1e-12) << r;
  }
}

TEST(MeshDistance, RefitAfterTranslationShiftsTheDistances) {
  auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  MeshDistance distance("box", box.vertices, box.triangles);
  const Eigen::Vector3d offset(0.35, -0.1, 0.2);  // more than the box is thick along y
  ASSERT_TRUE(distance.Update(test::Translated(box, offset).vertices));
  std::mt19937 rng(11);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, kCenter + offset, 0.6);
    ASSERT_NEAR(distance.SignedDistance(p, 2.0), BoxSignedDistance(p, kCenter + offset, kHalf),
                1e-12);
  }
  EXPECT_FALSE(distance.Update(Points::Zero(3, 3)));  // wrong size: refused, mesh kept
  EXPECT_NEAR(distance.SignedDistance(kCenter + offset, 2.0), -kHalf.minCoeff(), 1e-12);
}

TEST(MeshDistance, SeveralPiecesFormTheirUnion) {
  const Eigen::Vector3d center_b = kCenter + Eigen::Vector3d(0.4, 0.1, 0.0);  // overlaps
  const Eigen::Vector3d half_b(0.2, 0.2, 0.2);
  const auto a = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  const auto b = TessellatedBox(center_b, half_b, Eigen::Vector3i(3, 3, 3));
  Points vertices(a.vertices.rows() + b.vertices.rows(), 3);
  vertices << a.vertices, b.vertices;
  std::vector<Eigen::Vector3i> triangles = a.triangles;
  for (const Eigen::Vector3i& t : b.triangles) {
    triangles.push_back(t + Eigen::Vector3i::Constant(static_cast<int>(a.vertices.rows())));
  }
  const MeshDistance distance("two boxes", vertices, triangles);
  EXPECT_EQ(distance.num_pieces(), 2);
  std::mt19937 rng(5);
  int num_inside_both = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.5 * (kCenter + center_b), 0.6);
    const double da = BoxSignedDistance(p, kCenter, kHalf);
    const double db = BoxSignedDistance(p, center_b, half_b);
    const double got = distance.SignedDistance(p, 3.0);
    if (da >= 0.0 && db >= 0.0) {
      ASSERT_NEAR(got, std::min(da, db), 1e-12);  // outside both: exact
    } else {
      ASSERT_LT(got, 0.0);  // inside either is inside the union
      ASSERT_NEAR(got, std::min(da, db), 1e-12);  // the deeper piece's depth
      num_inside_both += da < 0.0 && db < 0.0;
    }
  }
  EXPECT_GT(num_inside_both, 10);
}

TEST(MeshDistance, PenetrationStatisticsCountMaximumAndP99) {
  const auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  const MeshDistance distance("box", box.vertices, box.triangles);
  // 100 points below the top face at depths 1, 2, ..., 100 mm, and 20 outside.
  Points points(120, 3);
  const Eigen::Vector3d top = kCenter + Eigen::Vector3d(0.017, kHalf.y(), 0.011);
  for (int k = 0; k < 100; ++k) points.row(k) = top - Eigen::Vector3d(0, 0.001 * (k + 1), 0);
  for (int k = 0; k < 20; ++k) points.row(100 + k) = top + Eigen::Vector3d(0, 0.01 * (k + 1), 0);
  const PenetrationStats stats = distance.MeasurePenetration(points, 0.5);
  EXPECT_EQ(stats.num_points, 120);
  EXPECT_EQ(stats.num_inside, 100);
  EXPECT_NEAR(stats.max_depth, 0.100, 1e-12);
  EXPECT_NEAR(stats.p99_depth, 0.099, 1e-12);  // nearest rank: the 99th of 100
  EXPECT_NEAR(distance.MaxPenetration(points, 0.5), 0.100, 1e-12);
}

TEST(MeshDistance, RefusesOpenOrBrokenMeshes) {
  auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(2, 2, 2));
  auto open = box.triangles;
  open.pop_back();
  EXPECT_THROW(MeshDistance("open", box.vertices, open), InputError);
  auto flipped = box.triangles;
  std::swap(flipped[0][1], flipped[0][2]);
  EXPECT_THROW(MeshDistance("flipped", box.vertices, flipped), InputError);
  auto out_of_range = box.triangles;
  out_of_range[3][2] = static_cast<int>(box.vertices.rows());
  EXPECT_THROW(MeshDistance("bad index", box.vertices, out_of_range), InputError);
  EXPECT_THROW(MeshDistance("empty", box.vertices, {}), InputError);
  try {
    MeshDistance("open", box.vertices, open);
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("mesh 'open'"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("edge ("), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace costume::sim
