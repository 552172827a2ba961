#pragma once
/// @file
/// Drawings of the superquadric collider's distance maps, kept for reuse when the same skin
/// comes back (superquadric_collider.h). Drawing a map from the skinned triangles is most of
/// the fast method's time per frame (docs/collision.md, "Reusing drawings"), and a looping
/// clip sampled on the simulation's frame grid poses the body identically every loop: each
/// segment's skin, in its own frame, repeats, and so does its drawing.
///
/// A drawing is found by a key of the skin it was drawn from: the segment and its skin
/// corners in the segment's frame, rounded to `quantum`. A hit thus hands back a drawing of a
/// skin whose every corner lies within one quantum (0.01 mm by default) of the skin asked
/// for; a skin that differs by more misses and is drawn. (Two different skins sharing a
/// 64-bit key is the only way to be handed a wrong drawing: about 1 in 10^12 for the
/// number of drawings a cache holds.)
///
/// Memory is reserved once, at construction, for the whole budget, and pages are touched
/// only as drawings are stored: a scene whose poses never repeat pays its stored drawings,
/// up to the budget, and nothing once it is full. When full, nothing more is stored and
/// nothing is evicted: for a loop longer than the budget, the stored start of the loop
/// stays useful every pass (evicting the oldest would miss every time).

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace costume::sim {

/// Where one stored drawing lives and what it says of the whole map.
struct StoredMapDrawing {
  std::uint64_t key = 0;
  /// Offset of its nodes in the cache's arena; its node count.
  std::size_t offset = 0;
  int num_nodes = 0;
  /// The skin's bounds at the drawing, without the thickness (SuperquadricSegment::
  /// drawn_skin_box, drawn_skin_farthest).
  Eigen::AlignedBox3d skin_box;
  double skin_farthest = 0.0;
};

/// One node of a drawing as stored and read, 8 bytes: the skin's radius along the node's
/// ray in steps of its map's radius step (SuperquadricSegment::radius_step, 10–30 µm),
/// negative when the node is capped (its ray saw no skin), and the skin's unit normal in
/// steps of 1/32767 (0.002°). Queries read nodes scattered over maps the size of the
/// caches: half the bytes of a node holding the radius and the tangent plane's distance
/// in single precision is half the memory they wait for (the plane is radius × normal·ray,
/// from the node's ray).
struct StoredMapNode {
  std::int16_t radius = 0;
  std::array<std::int16_t, 3> normal{};
  static constexpr double kNormalScale = 32767.0;
  static constexpr int kMaxRadiusSteps = 32767;
};

/// `x` rounded to the nearest integer (half away from zero); 0 for a non-finite or huge
/// `x`. Inline: std::lround is a library call on the baseline x86-64 this builds for, and
/// a key rounds every corner of a skin, a drawing four numbers per node.
inline std::int64_t RoundToInteger(double x) {
  if (!(std::abs(x) < 4e18)) return 0;
  return static_cast<std::int64_t>(x + (x >= 0.0 ? 0.5 : -0.5));
}

/// Counters of a SkinMapCache [-], [bytes].
struct SkinMapCacheStats {
  long long num_hits = 0;
  long long num_misses = 0;
  long long num_stored = 0;
  /// Drawings that found the budget full and were not stored.
  long long num_refused = 0;
  std::size_t bytes_used = 0;
  std::size_t budget_bytes = 0;
};

class SkinMapCache {
 public:
  /// A cache of at most `budget_bytes` of drawings' nodes (0: none is stored, every lookup
  /// misses and costs nothing), keyed by corners rounded to `quantum` [m] > 0. The records
  /// and the lookup table add about 3 % to the budget. Allocates (reserves) it all here.
  /// Throws InputError for a non-positive or non-finite quantum.
  explicit SkinMapCache(std::size_t budget_bytes = 0, double quantum = 1e-5);

  bool enabled() const { return budget_bytes_ > 0; }
  /// The rounding of the keys' corners [m].
  double quantum() const { return quantum_; }

  /// The key of segment `segment`'s skin `corners` (its frame) [m]. Never throws or
  /// allocates.
  std::uint64_t Key(int segment, const std::vector<Eigen::Vector3d>& corners) const;

  /// The drawing stored under `key`, or null; counts a hit or a miss. Never throws or
  /// allocates.
  const StoredMapDrawing* Find(std::uint64_t key);
  /// The nodes of a found drawing.
  const StoredMapNode* Nodes(const StoredMapDrawing& drawing) const {
    return arena_.data() + drawing.offset;
  }

  /// Room for a drawing of `num_nodes` nodes under `key`, whose lookup has just missed:
  /// its nodes to fill and its record, or null when the budget or the table is full
  /// (nothing is stored then). Never throws or allocates.
  StoredMapDrawing* Reserve(std::uint64_t key, int num_nodes, StoredMapNode*& nodes);

  /// Forgets every stored drawing; the reserved memory stays for new ones. The nodes handed
  /// out before must not be read again. Never throws or allocates.
  void Clear();

  const SkinMapCacheStats& stats() const { return stats_; }

 private:
  std::size_t budget_bytes_ = 0;
  double quantum_ = 1e-5;
  double inverse_quantum_ = 1e5;
  /// Node data of every stored drawing, back to back (capacity: the budget).
  std::vector<StoredMapNode> arena_;
  /// Open addressing over `table_` (a power of two in size, kept at most half full):
  /// indices into `drawings_` + 1, 0 for an empty slot.
  std::vector<int> table_;
  std::vector<StoredMapDrawing> drawings_;
  SkinMapCacheStats stats_;
};

}  // namespace costume::sim
