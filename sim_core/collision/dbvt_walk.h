#pragma once
/// @file
/// The depth-first walk of a Bullet btDbvt that the mesh distance and the mesh collider
/// share (internal to sim_core: it includes Bullet, which sim_core links privately).

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <vector>

namespace costume::sim {

/// Depth-first walk of `tree` on the scratch `stack`: a node `enter` refuses is pruned, an
/// internal node's child `first_child` names (0 or 1) is taken before the other, and
/// `leaf` visits each leaf entered, ending the walk when it returns false. Returns false
/// when a leaf ended it. Allocates only when `stack` must grow.
template <typename Enter, typename FirstChild, typename Leaf>
bool WalkTree(const btDbvt& tree, std::vector<const btDbvtNode*>& stack, Enter&& enter,
              FirstChild&& first_child, Leaf&& leaf) {
  stack.clear();
  if (tree.m_root != nullptr) stack.push_back(tree.m_root);
  while (!stack.empty()) {
    const btDbvtNode* node = stack.back();
    stack.pop_back();
    if (!enter(node)) continue;
    if (node->isinternal()) {
      const int first = first_child(node);
      stack.push_back(node->childs[1 - first]);
      stack.push_back(node->childs[first]);
      continue;
    }
    if (!leaf(node)) return false;
  }
  return true;
}

}  // namespace costume::sim
