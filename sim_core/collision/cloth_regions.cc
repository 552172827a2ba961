#include "sim_core/collision/cloth_regions.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// The hierarchy while it is built: a node's children (build ids) or, for a base region,
/// its particles.
struct BuildNode {
  std::vector<int> children;
  std::vector<int> particles;
};

bool IsLattice(const ClothModel& cloth) {
  return cloth.lattice_rows() > 0 && cloth.lattice_cols() > 0 &&
         static_cast<long long>(cloth.lattice_rows()) * cloth.lattice_cols() ==
             cloth.num_particles();
}

/// Lattice blocks of about n × n particles (block edges spread evenly), merged 2 × 2 per
/// level up to one root. Returns the build id of the root.
int BuildLattice(const ClothModel& cloth, int n, std::vector<BuildNode>& nodes) {
  const int rows = cloth.lattice_rows(), cols = cloth.lattice_cols();
  int grid_rows = std::clamp(static_cast<int>(std::lround(double(rows) / n)), 1, rows);
  int grid_cols = std::clamp(static_cast<int>(std::lround(double(cols) / n)), 1, cols);
  std::vector<int> grid(static_cast<std::size_t>(grid_rows) * grid_cols);
  for (int a = 0; a < grid_rows; ++a) {
    for (int b = 0; b < grid_cols; ++b) {
      BuildNode block;
      for (int i = a * rows / grid_rows; i < (a + 1) * rows / grid_rows; ++i) {
        for (int j = b * cols / grid_cols; j < (b + 1) * cols / grid_cols; ++j) {
          block.particles.push_back(i * cols + j);
        }
      }
      grid[a * grid_cols + b] = static_cast<int>(nodes.size());
      nodes.push_back(std::move(block));
    }
  }
  while (grid_rows > 1 || grid_cols > 1) {
    const int up_rows = (grid_rows + 1) / 2, up_cols = (grid_cols + 1) / 2;
    std::vector<int> up(static_cast<std::size_t>(up_rows) * up_cols);
    for (int a = 0; a < up_rows; ++a) {
      for (int b = 0; b < up_cols; ++b) {
        BuildNode parent;
        for (int i = 2 * a; i < std::min(2 * a + 2, grid_rows); ++i) {
          for (int j = 2 * b; j < std::min(2 * b + 2, grid_cols); ++j) {
            parent.children.push_back(grid[i * grid_cols + j]);
          }
        }
        if (parent.children.size() == 1) {  // no node holding a single child
          up[a * up_cols + b] = parent.children[0];
          continue;
        }
        up[a * up_cols + b] = static_cast<int>(nodes.size());
        nodes.push_back(std::move(parent));
      }
    }
    grid = std::move(up);
    grid_rows = up_rows;
    grid_cols = up_cols;
  }
  return grid[0];
}

/// Particles sharing a triangle edge with each particle (may repeat).
std::vector<std::vector<int>> ParticleNeighbours(const ClothModel& cloth) {
  std::vector<std::vector<int>> neighbours(cloth.num_particles());
  for (const Eigen::Vector3i& t : cloth.triangles()) {
    for (int k = 0; k < 3; ++k) {
      neighbours[t[k]].push_back(t[(k + 1) % 3]);
      neighbours[t[(k + 1) % 3]].push_back(t[k]);
    }
  }
  return neighbours;
}

/// Regions of up to `target` particles grown breadth first from the lowest unassigned
/// particle; appended to `nodes`, their build ids returned.
std::vector<int> GrowRegions(const std::vector<std::vector<int>>& neighbours, int target,
                             std::vector<BuildNode>& nodes) {
  const int n = static_cast<int>(neighbours.size());
  std::vector<char> taken(n, 0);
  std::vector<int> ids, queue;
  for (int seed = 0; seed < n; ++seed) {
    if (taken[seed]) continue;
    BuildNode region;
    queue.assign(1, seed);
    taken[seed] = 1;
    std::size_t head = 0;
    while (head < queue.size() && static_cast<int>(region.particles.size()) < target) {
      const int p = queue[head++];
      region.particles.push_back(p);
      for (int q : neighbours[p]) {
        if (!taken[q]) {
          taken[q] = 1;
          queue.push_back(q);
        }
      }
    }
    for (std::size_t i = head; i < queue.size(); ++i) taken[queue[i]] = 0;  // not taken
    ids.push_back(static_cast<int>(nodes.size()));
    nodes.push_back(std::move(region));
  }
  return ids;
}

/// One quadtree-like level over arbitrary topology: each node not yet taken joins up to
/// three untaken neighbours (nodes owning a particle across a triangle edge). `owner`
/// maps particles to positions in `level`; both are replaced by the next level's.
/// Returns whether any node merged.
bool MergeLevel(const std::vector<std::vector<int>>& neighbours, std::vector<int>& owner,
                std::vector<int>& level, std::vector<BuildNode>& nodes) {
  std::vector<std::vector<int>> adjacency(level.size());
  for (std::size_t p = 0; p < neighbours.size(); ++p) {
    for (int q : neighbours[p]) {
      if (owner[q] != owner[p]) adjacency[owner[p]].push_back(owner[q]);
    }
  }
  std::vector<int> parent_of(level.size(), -1);
  std::vector<int> up;
  bool any = false;
  for (std::size_t r = 0; r < level.size(); ++r) {
    if (parent_of[r] >= 0) continue;
    auto& candidates = adjacency[r];
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    BuildNode parent;
    const int id = static_cast<int>(up.size());
    parent.children.push_back(level[r]);
    parent_of[r] = id;
    for (int c : candidates) {
      if (parent.children.size() == 4) break;
      if (parent_of[c] >= 0) continue;
      parent.children.push_back(level[c]);
      parent_of[c] = id;
    }
    if (parent.children.size() == 1) {  // no node holding a single child
      up.push_back(level[r]);
      continue;
    }
    any = true;
    up.push_back(static_cast<int>(nodes.size()));
    nodes.push_back(std::move(parent));
  }
  for (int& o : owner) o = parent_of[o];
  level = std::move(up);
  return any;
}

/// Base regions grown over the triangles, merged level by level while anything merges.
/// Returns the roots' build ids (one per connected piece of cloth).
std::vector<int> BuildGeneral(const ClothModel& cloth, int n, std::vector<BuildNode>& nodes) {
  const auto neighbours = ParticleNeighbours(cloth);
  std::vector<int> level = GrowRegions(neighbours, n * n, nodes);
  std::vector<int> owner(cloth.num_particles(), 0);
  for (std::size_t r = 0; r < level.size(); ++r) {
    for (int p : nodes[level[r]].particles) owner[p] = static_cast<int>(r);
  }
  while (level.size() > 1 && MergeLevel(neighbours, owner, level, nodes)) {
  }
  return level;
}

}  // namespace

ClothRegions::ClothRegions(const ClothModel& cloth, int region_size)
    : corners_(cloth.triangles()) {
  if (region_size < 1 || region_size > 256) {
    throw InputError("cloth regions of '" + cloth.name() + "': region_size is " +
                     std::to_string(region_size) + " (allowed 1..256)");
  }
  std::vector<BuildNode> build;
  std::vector<int> roots;
  if (IsLattice(cloth)) {
    roots.push_back(BuildLattice(cloth, region_size, build));
  } else {
    roots = BuildGeneral(cloth, region_size, build);
  }
  // Lay the nodes out breadth first from the roots, so children are contiguous and come
  // after their parent.
  std::vector<int> order = roots;
  for (std::size_t k = 0; k < order.size(); ++k) {
    for (int c : build[order[k]].children) order.push_back(c);
  }
  nodes_.resize(order.size());
  num_roots_ = static_cast<int>(roots.size());
  std::vector<int> index_of(build.size(), -1);
  for (std::size_t k = 0; k < order.size(); ++k) index_of[order[k]] = static_cast<int>(k);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const BuildNode& b = build[order[k]];
    ClothRegionNode& node = nodes_[k];
    node.num_children = static_cast<int>(b.children.size());
    if (node.num_children > 0) node.first_child = index_of[b.children[0]];
    for (int c : b.children) nodes_[index_of[c]].parent = static_cast<int>(k);
    if (node.num_children == 0) ++num_base_regions_;
  }
  std::vector<int> depth(nodes_.size(), 0);
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    if (nodes_[k].parent >= 0) depth[k] = depth[nodes_[k].parent] + 1;
    max_depth_ = std::max(max_depth_, depth[k]);
  }
  // Particle ranges: base regions in depth-first order, so each node's range is the
  // concatenation of its children's.
  std::vector<int> stack(roots.rbegin(), roots.rend());
  std::vector<int> leaf_of(cloth.num_particles(), 0);
  for (int& s : stack) s = index_of[s];
  while (!stack.empty()) {
    const int k = stack.back();
    stack.pop_back();
    ClothRegionNode& node = nodes_[k];
    for (int c = node.num_children - 1; c >= 0; --c) stack.push_back(node.first_child + c);
    if (node.num_children > 0) continue;
    node.first = static_cast<int>(particles_.size());
    for (int p : build[order[k]].particles) {
      particles_.push_back(p);
      leaf_of[p] = k;
    }
    node.count = static_cast<int>(particles_.size()) - node.first;
  }
  for (int k = num_nodes() - 1; k >= 0; --k) {
    ClothRegionNode& node = nodes_[k];
    if (node.num_children == 0) continue;
    node.first = nodes_[node.first_child].first;
    node.count = 0;
    for (int c = 0; c < node.num_children; ++c) node.count += nodes_[node.first_child + c].count;
  }
  // Each triangle belongs to the base region of its first corner (a counting sort).
  std::vector<int> start(nodes_.size() + 1, 0);
  for (const Eigen::Vector3i& t : corners_) ++start[leaf_of[t[0]] + 1];
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    nodes_[k].first_triangle = start[k];
    nodes_[k].num_triangles = start[k + 1];
    start[k + 1] += start[k];
  }
  triangles_.resize(corners_.size());
  for (std::size_t t = 0; t < corners_.size(); ++t) {
    triangles_[start[leaf_of[corners_[t][0]]]++] = static_cast<int>(t);
  }
  normals_.resize(corners_.size());
  norms_.resize(corners_.size());
  reached_.assign(nodes_.size(), 0);
  selected_.reserve(nodes_.size());
}

namespace {

/// A base region's cone from its triangles' normals (area-weighted mean axis, then the
/// widest normal); returns the triangles tested. `normals` is scratch for `count`
/// vectors, `norms` for their lengths.
int LeafCone(const Points& x, const std::vector<Eigen::Vector3i>& corners, const int* triangles,
             int count, Eigen::Vector3d* normals, double* norms, ClothRegionNode& node) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (int j = 0; j < count; ++j) {
    const Eigen::Vector3i& c = corners[triangles[j]];
    const Eigen::Vector3d a = x.row(c[0]).transpose();
    normals[j] = (x.row(c[1]).transpose() - a).cross(x.row(c[2]).transpose() - a);
    norms[j] = normals[j].norm();
    sum += normals[j];
    weight += norms[j];
  }
  node.cone_weight = weight;
  node.cone_angle = 0.0;
  if (!(weight > 0.0)) return count;  // no area: no normal to hold
  const double length = sum.norm();
  if (!(length > 1e-12 * weight)) {
    node.cone_angle = kPi;
    return count;
  }
  node.cone_axis = sum / length;
  // The widest normal has the smallest cos = axis·n/|n|; compared without dividing.
  double min_cos = 1.0;
  for (int j = 0; j < count; ++j) {
    const double dot = node.cone_axis.dot(normals[j]);
    if (norms[j] > 0.0 && dot < min_cos * norms[j]) min_cos = dot / norms[j];
  }
  node.cone_angle = std::acos(std::clamp(min_cos, -1.0, 1.0));
  if (!(node.cone_angle >= 0.0)) node.cone_angle = kPi;  // NaN positions
  return count;
}

/// A parent's cone holding its children's cones.
void ParentCone(const ClothRegionNode* children, int count, ClothRegionNode& node) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (int c = 0; c < count; ++c) {
    if (children[c].cone_weight > 0.0) {
      sum += children[c].cone_weight * children[c].cone_axis;
      weight += children[c].cone_weight;
    }
  }
  node.cone_weight = weight;
  node.cone_angle = 0.0;
  if (!(weight > 0.0)) return;
  const double length = sum.norm();
  if (!(length > 1e-12 * weight)) {
    node.cone_angle = kPi;
    return;
  }
  node.cone_axis = sum / length;
  double angle = 0.0;
  for (int c = 0; c < count; ++c) {
    if (!(children[c].cone_weight > 0.0)) continue;
    const double cos_between = node.cone_axis.dot(children[c].cone_axis);
    const double between = std::acos(std::clamp(cos_between, -1.0, 1.0));
    angle = std::max(angle, between + children[c].cone_angle);
  }
  node.cone_angle = angle >= 0.0 ? std::min(angle, kPi) : kPi;  // NaN → not flat
}

}  // namespace

long long ClothRegions::Refit(const Points& positions, const double* half_extents, bool cones,
                             int cone_period) {
  long long tests = 0;
  // Base regions whose cone is refreshed this call: all the first time (and after a call
  // without cones), then one in every cone_period, taking turns.
  cone_period = cones_current_ ? std::max(cone_period, 1) : 1;
  const int phase = cone_phase_ % cone_period;
  cone_phase_ = phase + 1;
  cones_current_ = cones;
  int leaf = 0;
  // Children have larger indices than their parent: backwards, children come first.
  for (int k = num_nodes() - 1; k >= 0; --k) {
    ClothRegionNode& node = nodes_[k];
    node.box_min.setConstant(kInf);
    node.box_max.setConstant(-kInf);
    if (node.num_children > 0) {
      const ClothRegionNode* children = &nodes_[node.first_child];
      for (int c = 0; c < node.num_children; ++c) {
        node.box_min = node.box_min.cwiseMin(children[c].box_min);
        node.box_max = node.box_max.cwiseMax(children[c].box_max);
      }
      if (cones) {
        ParentCone(children, node.num_children, node);
        tests += node.num_children;
      }
      continue;
    }
    for (int s = node.first; s < node.first + node.count; ++s) {
      const int p = particles_[s];
      const double half = half_extents[p];
      if (!(half >= 0.0)) continue;
      const Eigen::Vector3d x = positions.row(p).transpose();
      const Eigen::Vector3d extent = Eigen::Vector3d::Constant(half);
      node.box_min = node.box_min.cwiseMin(x - extent);
      node.box_max = node.box_max.cwiseMax(x + extent);
    }
    if (cones && leaf++ % cone_period == phase) {
      tests += LeafCone(positions, corners_, triangles_.data() + node.first_triangle,
                        node.num_triangles, normals_.data() + node.first_triangle,
                        norms_.data() + node.first_triangle, node);
    }
  }
  return tests;
}

const std::vector<int>& ClothRegions::Select(double flatness_angle) {
  selected_.clear();
  // reached_: 0 not visited (an ancestor was taken whole), 1 descended into, 2 taken.
  for (int k = 0; k < num_nodes(); ++k) {
    const ClothRegionNode& node = nodes_[k];
    if (node.parent >= 0 && reached_[node.parent] != 1) {
      reached_[k] = 0;
      continue;
    }
    if (node.num_children == 0 || node.cone_angle <= flatness_angle) {
      reached_[k] = 2;
      selected_.push_back(k);
    } else {
      reached_[k] = 1;
    }
  }
  return selected_;
}

}  // namespace costume::sim
