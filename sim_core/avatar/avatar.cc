#include "sim_core/avatar/avatar.h"

#include <cmath>

#include "sim_core/avatar/coordinate_bound.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

void ValidateInfluences(const AvatarData& data, const std::string& where) {
  const Eigen::Index n = data.rest_vertices.rows();
  if (data.influence_joints.rows() != n || data.influence_weights.rows() != n) {
    throw InputError(where + ": influence_joints has " +
                     std::to_string(data.influence_joints.rows()) + " rows and influence_weights " +
                     std::to_string(data.influence_weights.rows()) +
                     " (allowed: one per vertex of rest_vertices, " + std::to_string(n) + ")");
  }
  const int num_joints = data.skeleton->num_joints();
  for (Eigen::Index v = 0; v < n; ++v) {
    double sum = 0.0;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int joint = data.influence_joints(v, k);
      const double weight = data.influence_weights(v, k);
      if (joint < -1 || joint >= num_joints) {
        throw InputError(where + ": influence_joints of vertex " + std::to_string(v) + " = " +
                         std::to_string(joint) + " out of range (allowed -1.." +
                         std::to_string(num_joints - 1) + ")");
      }
      if (!std::isfinite(weight) || weight < 0.0) {
        throw InputError(where + ": influence_weights of vertex " + std::to_string(v) + " = " +
                         FormatValue(weight) + " (allowed: finite, >= 0)");
      }
      if (joint >= 0) sum += weight;
    }
    if (std::abs(sum - 1.0) > 1e-6) {
      throw InputError(where + ": influence_weights of vertex " + std::to_string(v) + " sum to " +
                       FormatValue(sum) + " (allowed: 1 within 1e-6)");
    }
  }
}

int DominantJoint(const AvatarData& data, Eigen::Index v) {
  int best = -1;
  double best_weight = -1.0;
  for (int k = 0; k < kMaxInfluences; ++k) {
    if (data.influence_joints(v, k) >= 0 && data.influence_weights(v, k) > best_weight) {
      best = data.influence_joints(v, k);
      best_weight = data.influence_weights(v, k);
    }
  }
  return best;
}

}  // namespace

std::shared_ptr<const Avatar> Avatar::Create(AvatarData data) {
  const std::string where = "avatar '" + data.name + "'";
  if (!data.skeleton) throw InputError(where + ": skeleton is missing (allowed: non-null)");
  if (data.rest_vertices.rows() == 0) {
    throw InputError(where + ": rest_vertices is empty (allowed: at least one vertex)");
  }
  const int n = static_cast<int>(data.rest_vertices.rows());
  for (int v = 0; v < n; ++v) {
    if (!data.rest_vertices.row(v).allFinite()) {
      throw InputError(where + ": rest_vertices row " + std::to_string(v) +
                       " is not finite (allowed: finite coordinates)");
    }
    RequireWithinReach(data.rest_vertices.row(v).transpose(),
                       where + ": rest_vertices row " + std::to_string(v) + " has coordinate",
                       "the origin");
  }
  for (std::size_t t = 0; t < data.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = data.triangles[t];
    if (tri.minCoeff() < 0 || tri.maxCoeff() >= n) {
      throw InputError(where + ": triangles[" + std::to_string(t) +
                       "] has a vertex index out of range (allowed 0.." + std::to_string(n - 1) +
                       ")");
    }
  }
  ValidateInfluences(data, where);
  return std::shared_ptr<const Avatar>(new Avatar(std::move(data)));
}

Avatar::Avatar(AvatarData data) : data_(std::move(data)) {
  const Skeleton& skeleton = *data_.skeleton;
  inverse_bind_.reserve(skeleton.num_joints());
  for (const Eigen::Isometry3d& rest : skeleton.rest_world()) {
    inverse_bind_.push_back(rest.inverse());
  }
  segments_.resize(data_.rest_vertices.rows());
  for (Eigen::Index v = 0; v < data_.rest_vertices.rows(); ++v) {
    const int joint = DominantJoint(data_, v);
    if (joint >= 0) segments_[v] = skeleton.HAnimSegmentOf(joint);
  }
}

bool SameRestSkin(const Avatar& a, const Avatar& b) {
  constexpr double kTolerance = 1e-6;  // [m]: an importer's rounding, not another body
  return a.num_vertices() == b.num_vertices() &&
         (a.rest_vertices() - b.rest_vertices()).cwiseAbs().maxCoeff() <= kTolerance;
}

void SkinVertices(const Avatar& avatar, const std::vector<Eigen::Isometry3d>& joint_world,
                  std::vector<Eigen::Isometry3d>& skinning, Points& vertices) {
  const std::vector<Eigen::Isometry3d>& inverse_bind = avatar.inverse_bind();
  skinning.resize(inverse_bind.size());
  for (std::size_t j = 0; j < inverse_bind.size(); ++j) {
    skinning[j] = joint_world[j] * inverse_bind[j];
  }
  const AvatarData& data = avatar.data();
  const Eigen::Index n = data.rest_vertices.rows();
  vertices.resize(n, 3);
  for (Eigen::Index v = 0; v < n; ++v) {
    const Eigen::Vector3d rest = data.rest_vertices.row(v).transpose();
    Eigen::Vector3d skinned = Eigen::Vector3d::Zero();
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int joint = data.influence_joints(v, k);
      if (joint < 0) continue;
      skinned += data.influence_weights(v, k) * (skinning[joint] * rest);
    }
    vertices.row(v) = skinned.transpose();
  }
}

}  // namespace costume::sim
