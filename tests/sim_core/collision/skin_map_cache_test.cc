// The store of map drawings: keys that agree exactly when every corner rounds to the same
// quantum, lookups that find what was stored, and a budget that is never exceeded.
#include "sim_core/collision/skin_map_cache.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kQuantum = 1e-5;  // [m]

/// Corners a tenth of a quantum above multiples of it, so that moving one by less than
/// four tenths keeps its rounding.
std::vector<Eigen::Vector3d> Corners() {
  std::vector<Eigen::Vector3d> corners;
  for (int i = 0; i < 50; ++i) {
    corners.push_back(kQuantum * Eigen::Vector3d(1000 + 7 * i, -300 + i, 20 * i) +
                      Eigen::Vector3d::Constant(0.1 * kQuantum));
  }
  return corners;
}

TEST(SkinMapCache, KeysAgreeWithinTheQuantumAndDifferBeyondIt) {
  const SkinMapCache cache(1 << 20, kQuantum);
  const std::vector<Eigen::Vector3d> corners = Corners();
  std::vector<Eigen::Vector3d> near = corners, moved = corners, shorter = corners;
  for (Eigen::Vector3d& c : near) c.y() += 0.3 * kQuantum;
  moved[17].x() += 1.5 * kQuantum;
  shorter.pop_back();
  const std::uint64_t key = cache.Key(3, corners);
  EXPECT_EQ(cache.Key(3, near), key);
  EXPECT_NE(cache.Key(3, moved), key);
  EXPECT_NE(cache.Key(3, shorter), key);
  EXPECT_NE(cache.Key(4, corners), key);  // another segment's skin
}

TEST(SkinMapCache, FindsWhatWasStoredAndCountsHitsAndMisses) {
  SkinMapCache cache(1 << 20, kQuantum);
  const std::uint64_t key = cache.Key(0, Corners());
  EXPECT_EQ(cache.Find(key), nullptr);
  StoredMapNode* nodes = nullptr;
  StoredMapDrawing* stored = cache.Reserve(key, 10, nodes);
  ASSERT_NE(stored, nullptr);
  ASSERT_NE(nodes, nullptr);
  for (int n = 0; n < 10; ++n) nodes[n].radius = 0.1f * static_cast<float>(n);
  stored->bounding_radius = 0.25;
  const StoredMapDrawing* found = cache.Find(key);
  ASSERT_NE(found, nullptr);
  EXPECT_EQ(found->num_nodes, 10);
  EXPECT_EQ(found->bounding_radius, 0.25);
  EXPECT_FLOAT_EQ(cache.Nodes(*found)[7].radius, 0.7f);
  EXPECT_EQ(cache.Find(key + 1), nullptr);
  EXPECT_EQ(cache.stats().num_hits, 1);
  EXPECT_EQ(cache.stats().num_misses, 2);
  EXPECT_EQ(cache.stats().num_stored, 1);
}

TEST(SkinMapCache, StoresNothingBeyondItsBudget) {
  constexpr int kNodes = 100;
  SkinMapCache cache(kNodes * sizeof(StoredMapNode), kQuantum);
  StoredMapNode* nodes = nullptr;
  EXPECT_NE(cache.Reserve(1, 60, nodes), nullptr);
  EXPECT_EQ(cache.Reserve(2, 60, nodes), nullptr);  // 120 nodes would not fit
  EXPECT_NE(cache.Reserve(3, 40, nodes), nullptr);  // exactly the rest
  EXPECT_EQ(cache.Reserve(4, 1, nodes), nullptr);
  EXPECT_EQ(cache.stats().num_refused, 2);
  EXPECT_EQ(cache.Find(2), nullptr);
  EXPECT_NE(cache.Find(3), nullptr);
  EXPECT_GE(cache.stats().bytes_used, kNodes * sizeof(StoredMapNode));
}

TEST(SkinMapCache, ADisabledCacheStoresNothing) {
  SkinMapCache cache(0, kQuantum);
  EXPECT_FALSE(cache.enabled());
  StoredMapNode* nodes = nullptr;
  EXPECT_EQ(cache.Reserve(1, 1, nodes), nullptr);
  EXPECT_EQ(cache.Find(1), nullptr);
  EXPECT_EQ(cache.stats().bytes_used, 0u);
}

TEST(SkinMapCache, RefusesABadQuantum) {
  EXPECT_THROW(SkinMapCache(1024, 0.0), InputError);
  EXPECT_THROW(SkinMapCache(1024, -1e-5), InputError);
  EXPECT_THROW(SkinMapCache(1024, std::numeric_limits<double>::quiet_NaN()), InputError);
}

TEST(StoredMapNode, NormalsComeBackWithinAHundredthOfADegree) {
  // Rounding to octahedral steps of 1/32767 turns a normal by about 2/32767 rad at most
  // (0.0035°; 0.0036° measured here); a hundredth of a degree bounds that with room.
  // Directions on the coordinate axes and planes, where the folding's signs switch, and
  // spread over the sphere.
  std::vector<Eigen::Vector3d> normals;
  for (int a = 0; a < 3; ++a) {
    normals.push_back(Eigen::Vector3d::Unit(a));
    normals.push_back(-Eigen::Vector3d::Unit(a));
  }
  normals.push_back(Eigen::Vector3d(1, -1, 0).normalized());
  normals.push_back(Eigen::Vector3d(-1, 0, -1).normalized());
  for (int i = 0; i < 20000; ++i) {
    // A golden-angle spiral: evenly spread, both hemispheres.
    const double z = 1.0 - (2.0 * i + 1.0) / 20000.0;
    const double angle = 2.399963229728653 * i, r = std::sqrt(1.0 - z * z);
    normals.push_back(Eigen::Vector3d(r * std::cos(angle), r * std::sin(angle), z));
  }
  double worst = 0.0;
  for (const Eigen::Vector3d& n : normals) {
    const Eigen::Vector3d back = DecodeMapNormal(EncodeMapNormal(n));
    EXPECT_NEAR(back.norm(), 1.0, 1e-12);
    worst = std::max(worst, std::atan2(n.cross(back).norm(), n.dot(back)));
  }
  EXPECT_LT(worst * 180.0 / M_PI, 0.01);
}

}  // namespace
}  // namespace costume::sim
