#include "sim_core/solver/constraints.h"

namespace costume::sim {

Constraints::Constraints(int num_particles)
    : kind_(num_particles, 0),
      normal_(num_particles, Eigen::Vector3d::Zero()),
      prescribed_(Eigen::VectorXd::Zero(3 * num_particles)) {
  constrained_.reserve(num_particles);
}

void Constraints::Clear() {
  for (int i : constrained_) {
    kind_[i] = 0;
    prescribed_.segment<3>(3 * i).setZero();
  }
  constrained_.clear();
}

void Constraints::Fix(int i, const Eigen::Vector3d& dv) {
  if (kind_[i] == 0) constrained_.push_back(i);
  kind_[i] = 3;
  prescribed_.segment<3>(3 * i) = dv;
}

void Constraints::ConstrainNormal(int i, const Eigen::Vector3d& normal, double dv_normal) {
  if (kind_[i] == 3) return;
  if (kind_[i] == 1) {
    Fix(i, prescribed_.segment<3>(3 * i) + dv_normal * normal);
    return;
  }
  constrained_.push_back(i);
  kind_[i] = 1;
  normal_[i] = normal;
  prescribed_.segment<3>(3 * i) = dv_normal * normal;
}

void Constraints::Filter(Eigen::VectorXd& v) const {
  for (int i : constrained_) {
    auto vi = v.segment<3>(3 * i);
    if (kind_[i] == 3) {
      vi.setZero();
    } else {
      vi -= normal_[i] * normal_[i].dot(vi);
    }
  }
}

}  // namespace costume::sim
