#include "sim_core/avatar/skeleton.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "sim_core/avatar/coordinate_bound.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

std::string Where(const std::string& skeleton, int index, const std::string& joint) {
  return "skeleton '" + skeleton + "', joint " + std::to_string(index) + " ('" + joint + "')";
}

void RequireRigid(const std::string& where, const Eigen::Isometry3d& transform) {
  if (!transform.matrix().allFinite()) {
    throw InputError(where + ": rest transform has non-finite entries");
  }
  const Eigen::Matrix3d r = transform.linear();
  const double error = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (error > 1e-6 || r.determinant() < 0.0) {
    throw InputError(where + ": rest transform is not a rotation (|RᵀR − I| = " +
                     FormatValue(error) + ", det = " + FormatValue(r.determinant()) +
                     "; allowed: orthonormal, det +1, within 1e-6)");
  }
}

}  // namespace

std::shared_ptr<const Skeleton> Skeleton::Create(std::string name, std::vector<Joint> joints) {
  if (joints.empty()) throw InputError("skeleton '" + name + "': has no joints");
  std::unordered_set<std::string> names;
  std::array<bool, kNumHAnimJoints> hanim_used{};
  for (int i = 0; i < static_cast<int>(joints.size()); ++i) {
    const Joint& joint = joints[i];
    const std::string where = Where(name, i, joint.name);
    if (joint.name.empty()) throw InputError(where + ": empty name");
    if (!names.insert(joint.name).second) throw InputError(where + ": name used twice");
    if (joint.parent < -1 || joint.parent >= i) {
      throw InputError(where + ": parent index " + std::to_string(joint.parent) +
                       " out of range (allowed: -1 for a root, or 0.." + std::to_string(i - 1) +
                       ", parents before children)");
    }
    RequireRigid(where, joint.rest_local);
    RequireWithinReach(joint.rest_local.translation(), where + ": rest offset coordinate",
                       "the parent");
    if (joint.hanim) {
      bool& used = hanim_used[static_cast<int>(*joint.hanim)];
      if (used) {
        throw InputError(where + ": H-Anim joint '" + std::string(HAnimName(*joint.hanim)) +
                         "' is mapped twice");
      }
      used = true;
    }
  }
  return std::shared_ptr<const Skeleton>(new Skeleton(std::move(name), std::move(joints)));
}

Skeleton::Skeleton(std::string name, std::vector<Joint> joints)
    : name_(std::move(name)), joints_(std::move(joints)) {
  hanim_index_.fill(-1);
  rest_world_.resize(joints_.size());
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const Joint& joint = joints_[i];
    rest_world_[i] =
        joint.parent < 0 ? joint.rest_local : rest_world_[joint.parent] * joint.rest_local;
    if (joint.hanim) hanim_index_[static_cast<int>(*joint.hanim)] = static_cast<int>(i);
  }
  FindSegments();
}

// Why the nearest bone where no ancestor is mapped: a rig's deform bones need not descend
// from each other. Rigify parents DEF-spine.002 (the chest) and the arms' twist bones to
// ORG and MCH bones under an unmapped "root", so 55 of 74 skin vertices at the waist of a
// Rigify avatar belonged to no segment, the waist was measured on 14 of 73, and the
// built-in skirt's waistband came out as a flat ring 0.9 m across.
void Skeleton::FindSegments() {
  const int n = static_cast<int>(joints_.size());
  // Each mapped joint's bone: from it to the mapped joints nearest below it in H-Anim's own
  // hierarchy (none for an end), which does not depend on how the file nests its bones.
  std::vector<std::vector<int>> mapped_children(n);
  for (int j = 0; j < n; ++j) {
    if (!joints_[j].hanim) continue;
    for (std::optional<HAnimJoint> up = HAnimParent(*joints_[j].hanim); up; up = HAnimParent(*up)) {
      if (const int parent = Find(*up); parent >= 0) {
        mapped_children[parent].push_back(j);
        break;
      }
    }
  }
  const auto distance_to_bone = [&](const Eigen::Vector3d& x, int j) {
    const Eigen::Vector3d a = rest_world_[j].translation();
    double best = (x - a).norm();
    for (int c : mapped_children[j]) {
      const Eigen::Vector3d ab = rest_world_[c].translation() - a;
      const double t = ab.squaredNorm() > 0 ? std::clamp((x - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0)
                                            : 0.0;
      best = std::min(best, (x - (a + t * ab)).norm());
    }
    return best;
  };
  segment_of_.assign(n, std::nullopt);
  for (int i = 0; i < n; ++i) {
    for (int j = i; j >= 0; j = joints_[j].parent) {
      if (joints_[j].hanim) {
        segment_of_[i] = joints_[j].hanim;
        break;
      }
    }
    if (segment_of_[i]) continue;
    double nearest = std::numeric_limits<double>::infinity();
    for (int j = 0; j < n; ++j) {
      if (!joints_[j].hanim) continue;
      const double d = distance_to_bone(rest_world_[i].translation(), j);
      if (d < nearest) {
        nearest = d;
        segment_of_[i] = joints_[j].hanim;
      }
    }
  }
}

int Skeleton::FindByName(const std::string& name) const {
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    if (joints_[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

std::optional<HAnimJoint> Skeleton::HAnimSegmentOf(int index) const {
  return index >= 0 && index < static_cast<int>(segment_of_.size()) ? segment_of_[index]
                                                                     : std::nullopt;
}

}  // namespace costume::sim
