#include "sim_core/collision/skin_map_cache.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

/// The drawings a cache may hold: one per 4 kB of budget (maps have from a few hundred to
/// tens of thousands of nodes of 8 bytes, most of them thousands).
constexpr std::size_t kBytesPerDrawingSlot = 4096;

constexpr std::uint64_t kPrime1 = 0x9E3779B185EBCA87ULL, kPrime2 = 0xC2B2AE3D27D4EB4FULL;

/// One round of xxHash64 (Collet): the next word into the running value.
std::uint64_t Round(std::uint64_t hash, std::uint64_t word) {
  hash += word * kPrime2;
  hash = std::rotl(hash, 31);
  return hash * kPrime1;
}

/// xxHash64's final avalanche: every bit of the running value reaches every output bit.
std::uint64_t Avalanche(std::uint64_t hash) {
  hash ^= hash >> 33;
  hash *= kPrime2;
  hash ^= hash >> 29;
  hash *= 0x165667B19E3779F9ULL;
  hash ^= hash >> 32;
  return hash;
}

}  // namespace

SkinMapCache::SkinMapCache(std::size_t budget_bytes, double quantum)
    : budget_bytes_(budget_bytes), quantum_(quantum) {
  if (!(quantum > 0.0) || !std::isfinite(quantum)) {
    throw InputError("skin map cache: quantum " + std::to_string(quantum) +
                     " m must be positive and finite");
  }
  inverse_quantum_ = 1.0 / quantum;
  stats_.budget_bytes = budget_bytes;
  if (budget_bytes == 0) return;
  arena_.reserve(budget_bytes / sizeof(StoredMapNode));
  const std::size_t max_drawings = std::max<std::size_t>(16, budget_bytes / kBytesPerDrawingSlot);
  drawings_.reserve(max_drawings);
  table_.assign(std::bit_ceil(2 * max_drawings), 0);
}

std::uint64_t SkinMapCache::Key(int segment, const std::vector<Eigen::Vector3d>& corners) const {
  std::uint64_t hash = Round(kPrime1, static_cast<std::uint64_t>(segment));
  for (const Eigen::Vector3d& corner : corners) {
    for (int a = 0; a < 3; ++a) {
      hash = Round(hash, static_cast<std::uint64_t>(RoundToInteger(corner[a] * inverse_quantum_)));
    }
  }
  return Avalanche(hash ^ corners.size());
}

const StoredMapDrawing* SkinMapCache::Find(std::uint64_t key) {
  if (!enabled()) return nullptr;
  const std::size_t mask = table_.size() - 1;
  for (std::size_t slot = key & mask;; slot = (slot + 1) & mask) {
    const int entry = table_[slot];
    if (entry == 0) break;
    if (drawings_[entry - 1].key == key) {
      ++stats_.num_hits;
      return &drawings_[entry - 1];
    }
  }
  ++stats_.num_misses;
  return nullptr;
}

StoredMapDrawing* SkinMapCache::Reserve(std::uint64_t key, int num_nodes,
                                        StoredMapNode*& nodes) {
  if (!enabled()) return nullptr;
  const std::size_t count = static_cast<std::size_t>(num_nodes);
  if (arena_.size() + count > arena_.capacity() || drawings_.size() == drawings_.capacity()) {
    ++stats_.num_refused;
    return nullptr;
  }
  const std::size_t mask = table_.size() - 1;
  std::size_t slot = key & mask;
  while (table_[slot] != 0) slot = (slot + 1) & mask;
  StoredMapDrawing drawing;
  drawing.key = key;
  drawing.offset = arena_.size();
  drawing.num_nodes = num_nodes;
  arena_.resize(arena_.size() + count);  // within the reserved capacity: no allocation
  drawings_.push_back(drawing);
  table_[slot] = static_cast<int>(drawings_.size());
  ++stats_.num_stored;
  stats_.bytes_used = arena_.size() * sizeof(StoredMapNode) + drawings_.size() * sizeof(StoredMapDrawing);
  nodes = arena_.data() + drawing.offset;
  return &drawings_.back();
}

void SkinMapCache::Clear() {
  arena_.clear();  // the capacity stays reserved
  drawings_.clear();
  std::fill(table_.begin(), table_.end(), 0);
  stats_.bytes_used = 0;
}

}  // namespace costume::sim
