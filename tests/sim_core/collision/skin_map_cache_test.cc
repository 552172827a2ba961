// The store of map drawings: keys that agree exactly when every corner rounds to the same
// quantum, lookups that find what was stored, and a budget that is never exceeded.
#include "sim_core/collision/skin_map_cache.h"

#include <gtest/gtest.h>

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
  for (int n = 0; n < 10; ++n) nodes[n].radius = static_cast<std::int16_t>(100 * n);
  stored->skin_farthest = 0.25;
  const StoredMapDrawing* found = cache.Find(key);
  ASSERT_NE(found, nullptr);
  EXPECT_EQ(found->num_nodes, 10);
  EXPECT_EQ(found->skin_farthest, 0.25);
  EXPECT_EQ(cache.Nodes(*found)[7].radius, 700);
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

TEST(SkinMapCache, ClearedItFindsNothingAndHasItsWholeBudgetAgain) {
  constexpr int kNodes = 100;
  SkinMapCache cache(kNodes * sizeof(StoredMapNode), kQuantum);
  StoredMapNode* nodes = nullptr;
  ASSERT_NE(cache.Reserve(1, 70, nodes), nullptr);
  EXPECT_EQ(cache.Reserve(2, 70, nodes), nullptr);
  cache.Clear();
  EXPECT_EQ(cache.stats().bytes_used, 0u);
  EXPECT_EQ(cache.Find(1), nullptr);
  ASSERT_NE(cache.Reserve(2, 70, nodes), nullptr);
  nodes[69].radius = 7;
  ASSERT_NE(cache.Find(2), nullptr);
  EXPECT_EQ(cache.Nodes(*cache.Find(2))[69].radius, 7);
  EXPECT_NE(cache.Reserve(3, 30, nodes), nullptr);  // exactly the rest
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

}  // namespace
}  // namespace costume::sim
