// Signed distance to closed meshes against closed forms: a tessellated box (exact), a
// sphere (within the tessellation error computed here), signs at the box's edges and
// corners, refitting after motion, bodies of several pieces, penetration statistics, and
// inside/outside by winding number where a mesh passes through itself (prisms over
// self-crossing polygons, whose winding numbers are known).
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

// The box's inside by winding number: random points, and points on the planes of its
// tessellation's edges and vertices, where rays are most likely to graze an edge.
TEST(MeshDistance, InsideMatchesTheBoxEvenOnItsGridLines) {
  const Eigen::Vector3i cells(4, 3, 5);
  const auto box = TessellatedBox(kCenter, kHalf, cells);
  const MeshDistance distance("box", box.vertices, box.triangles);
  std::mt19937 rng(11);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 1000; ++i) points.push_back(RandomPoint(rng, kCenter, 0.6));
  // Every combination of grid coordinates (from 1.5 box sizes out to the centre).
  for (int i = -6; i <= 6; ++i) {
    for (int j = -5; j <= 5; ++j) {
      for (int k = -7; k <= 7; ++k) {
        const Eigen::Vector3d grid(i * 2.0 * kHalf.x() / cells.x(), j * 2.0 * kHalf.y() / cells.y(),
                                   k * 2.0 * kHalf.z() / cells.z());
        points.push_back(kCenter + 0.5 * grid);
      }
    }
  }
  int num_inside = 0, num_checked = 0;
  for (const Eigen::Vector3d& p : points) {
    const double expected = BoxSignedDistance(p, kCenter, kHalf);
    if (std::abs(expected) < 1e-9) continue;  // on the surface
    ASSERT_EQ(distance.Inside(p), expected < 0.0) << p.transpose();
    ASSERT_NEAR(distance.PenetrationDepth(p, 2.0), std::max(0.0, -expected), 1e-12);
    num_inside += expected < 0.0;
    ++num_checked;
  }
  EXPECT_GT(num_inside, 300);
  EXPECT_GT(num_checked, 2500);
}

/// A closed prism of height `height` [m] over the polygon `corners` (x, y) [m], which may
/// cross itself: side walls from each edge, caps fanned from the first corner. The
/// winding number inside the prism is the polygon's (a fan's signed triangles sum to it).
test::TestMesh PolygonPrism(const std::vector<Eigen::Vector2d>& corners, double height) {
  const int n = static_cast<int>(corners.size());
  test::TestMesh mesh;
  mesh.vertices.resize(2 * n, 3);
  for (int i = 0; i < n; ++i) {
    mesh.vertices.row(i) << corners[i].x(), corners[i].y(), 0.0;
    mesh.vertices.row(n + i) << corners[i].x(), corners[i].y(), height;
  }
  for (int i = 1; i + 1 < n; ++i) {
    mesh.triangles.emplace_back(0, i + 1, i);          // bottom, facing −z
    mesh.triangles.emplace_back(n, n + i, n + i + 1);  // top, facing +z
  }
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;  // a counter-clockwise edge's wall faces to its right
    mesh.triangles.emplace_back(i, j, n + j);
    mesh.triangles.emplace_back(i, n + j, n + i);
  }
  return mesh;
}

// Where skinning folds skin through itself, the nearest feature's pseudonormal can point
// either way; the winding number cannot. A prism over a figure eight: its left loop runs
// counter-clockwise (winding +1, inside), its right loop clockwise (−1: turned inside out,
// outside), and beside the right loop's outer wall (winding 0) that wall's normal faces
// away from the point, so the pseudonormal calls it inside. A polygon running twice around
// a square: between its loops the winding is 1 (inside) while the nearest wall, the inner
// loop's, faces the point.
TEST(MeshDistance, PenetrationFollowsTheWindingWhereTheMeshPassesThroughItself) {
  const double s = 0.1, z = 0.05;
  const auto eight = PolygonPrism({{0, 0}, {2 * s, s}, {2 * s, 0}, {0, s}}, 2 * z);
  const MeshDistance eight_distance("figure eight", eight.vertices, eight.triangles);
  const Eigen::Vector3d in_left(0.3 * s, 0.5 * s, z), in_right(1.7 * s, 0.5 * s, z);
  const Eigen::Vector3d beside_right(2.3 * s, 0.5 * s, z), beside_left(-0.3 * s, 0.5 * s, z);
  EXPECT_TRUE(eight_distance.Inside(in_left));
  EXPECT_NEAR(eight_distance.PenetrationDepth(in_left, 1.0), 0.3 * s, 1e-12);  // the x = 0 wall
  EXPECT_FALSE(eight_distance.Inside(in_right));
  EXPECT_LT(eight_distance.SignedDistance(beside_right, 1.0), 0.0);  // the pseudonormal's error
  EXPECT_FALSE(eight_distance.Inside(beside_right));
  EXPECT_EQ(eight_distance.PenetrationDepth(beside_right, 1.0), 0.0);
  EXPECT_FALSE(eight_distance.Inside(beside_left));

  // Outer square 0..3, then an inner square 1..2, both counter-clockwise.
  const auto twice = PolygonPrism({{0, 0}, {3 * s, 0}, {3 * s, 3 * s}, {0, 3 * s}, {s, s},
                                   {2 * s, s}, {2 * s, 2 * s}, {s, 2 * s}},
                                  2 * z);
  const MeshDistance twice_distance("twice around", twice.vertices, twice.triangles);
  const Eigen::Vector3d between(2.2 * s, 1.5 * s, z), centre(1.5 * s, 1.5 * s, z);
  EXPECT_GT(twice_distance.SignedDistance(between, 1.0), 0.0);  // the pseudonormal's error
  EXPECT_TRUE(twice_distance.Inside(between));
  EXPECT_NEAR(twice_distance.PenetrationDepth(between, 1.0), 0.2 * s, 1e-12);  // the x = 2s wall
  EXPECT_TRUE(twice_distance.Inside(centre));  // winding 2
  EXPECT_FALSE(twice_distance.Inside(Eigen::Vector3d(3.2 * s, 1.5 * s, z)));
  Points points(3, 3);
  points << in_left.transpose(), beside_right.transpose(), in_right.transpose();
  const PenetrationStats stats = eight_distance.MeasurePenetration(points, 1.0);
  EXPECT_EQ(stats.num_inside, 1);
  EXPECT_NEAR(stats.max_depth, 0.3 * s, 1e-12);
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

// The face normals follow an Update at the next query (they are computed lazily). Turned
// half a turn about its own vertical axis, the box's triangles swap sides: a triangle now on
// the +x side faced −x before, so a stale normal would put points outside it inside.
TEST(MeshDistance, ARotatedMeshIsSignedByItsNewNormals) {
  auto box = TessellatedBox(kCenter, kHalf, Eigen::Vector3i(4, 3, 5));
  MeshDistance distance("box", box.vertices, box.triangles);
  ASSERT_GT(distance.SignedDistance(kCenter + Eigen::Vector3d(kHalf.x() + 0.05, 0.01, 0.02), 2.0),
            0.0);
  Points turned = box.vertices;
  const Eigen::Matrix3d half_turn = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).matrix();
  for (Eigen::Index v = 0; v < turned.rows(); ++v) {
    turned.row(v) = (half_turn * (box.vertices.row(v).transpose() - kCenter) + kCenter).transpose();
  }
  ASSERT_TRUE(distance.Update(turned));
  std::mt19937 rng(12);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, kCenter, 0.6);
    ASSERT_NEAR(distance.SignedDistance(p, 2.0), BoxSignedDistance(p, kCenter, kHalf), 1e-12)
        << "at " << p.transpose();
  }
}

// A large mesh built a second time takes copies of the first build's trees (MeshDistance
// keeps them): it answers every query as the first, to the bit, the nearest triangle named
// included, and it is its own, moved without moving the first.
TEST(MeshDistance, AMeshBuiltAgainReusesTheTreesAndIsItsOwn) {
  const Eigen::Vector3d half(0.31, 0.17, 0.23);  // a box no other test builds
  auto box = TessellatedBox(kCenter, half, Eigen::Vector3i(21, 19, 17));
  ASSERT_GE(box.triangles.size(), 2000u);
  const MeshDistance first("box", box.vertices, box.triangles);
  EXPECT_FALSE(first.reused_trees());
  MeshDistance second("box", box.vertices, box.triangles);
  EXPECT_TRUE(second.reused_trees());
  // Random points, and points 1 cm out from each grid vertex, whose nearest point is that
  // vertex in every triangle around it: which triangle is named depends on the order the
  // trees are walked in.
  std::vector<Eigen::Vector3d> points;
  std::mt19937 rng(13);
  for (int i = 0; i < 3000; ++i) points.push_back(RandomPoint(rng, kCenter, 0.5));
  for (Eigen::Index v = 0; v < box.vertices.rows(); ++v) {
    const Eigen::Vector3d q = box.vertices.row(v).transpose() - kCenter;
    Eigen::Index axis = 0;
    (q.cwiseAbs() - half).maxCoeff(&axis);  // a face the vertex lies on
    points.push_back(box.vertices.row(v).transpose() +
                     0.01 * std::copysign(1.0, q[axis]) * Eigen::Vector3d::Unit(axis));
  }
  for (const Eigen::Vector3d& p : points) {
    const SurfaceDistance a = first.Query(p, 2.0), b = second.Query(p, 2.0);
    ASSERT_EQ(a.signed_distance, b.signed_distance) << "at " << p.transpose();
    ASSERT_EQ(a.triangle, b.triangle) << "at " << p.transpose();
    ASSERT_EQ(a.closest_point, b.closest_point);
    ASSERT_EQ(first.Inside(p), second.Inside(p));
  }
  const Eigen::Vector3d offset(0.4, -0.1, 0.2);
  ASSERT_TRUE(second.Update(test::Translated(box, offset).vertices));
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, kCenter + 0.5 * offset, 0.7);
    ASSERT_NEAR(second.SignedDistance(p, 2.0), BoxSignedDistance(p, kCenter + offset, half),
                1e-12);
    ASSERT_NEAR(first.SignedDistance(p, 2.0), BoxSignedDistance(p, kCenter, half), 1e-12);
  }
}

TEST(MeshDistance, SeveralPiecesFormTheirUnionAndCanBeCountedApart) {
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
  // Counting only some pieces: inside exactly those boxes. Piece numbers are found from
  // the triangles, so the test does not assume which box is piece 0.
  const int piece_a = distance.piece_of(0);
  const int piece_b = distance.piece_of(static_cast<int>(a.triangles.size()));
  ASSERT_NE(piece_a, piece_b);
  std::vector<char> only_a(2, 0), only_b(2, 0);
  only_a[piece_a] = 1;
  only_b[piece_b] = 1;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d p = RandomPoint(rng, 0.5 * (kCenter + center_b), 0.6);
    const double da = BoxSignedDistance(p, kCenter, kHalf);
    const double db = BoxSignedDistance(p, center_b, half_b);
    if (std::abs(da) < 1e-9 || std::abs(db) < 1e-9) continue;  // on a face: either answer
    ASSERT_EQ(distance.Inside(p, &only_a), da < 0.0) << p.transpose();
    ASSERT_EQ(distance.Inside(p, &only_b), db < 0.0) << p.transpose();
    ASSERT_EQ(distance.Inside(p, nullptr), da < 0.0 || db < 0.0) << p.transpose();
  }
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
