#pragma once
/// @file
/// Per-particle velocity constraints of one implicit step (Baraff & Witkin 1998 §5.1):
/// each particle is free, slides on a plane (a contact: one constrained direction) or is
/// fixed (a pin). The filter S projects a velocity change onto the allowed directions.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace costume::sim {

class Constraints {
 public:
  /// Allocates for `num_particles`; every later call is allocation-free.
  explicit Constraints(int num_particles);

  /// Makes every particle free.
  void Clear();
  /// Fixes particle i: Δv_i = dv [m/s]. Overrides any contact on i.
  void Fix(int i, const Eigen::Vector3d& dv);
  /// Constrains particle i along unit `normal`: normal·Δv_i = dv_normal [m/s]. A second
  /// contact on the same particle fixes it (Δv keeps both targets approximately: we fix it
  /// at the sum of both prescribed changes, which for rare corner contacts is safe).
  void ConstrainNormal(int i, const Eigen::Vector3d& normal, double dv_normal);

  /// v ← S v: removes the constrained components. Never allocates.
  void Filter(Eigen::VectorXd& v) const;
  /// The prescribed Δv (3n): constrained components as set, zero elsewhere.
  const Eigen::VectorXd& prescribed() const { return prescribed_; }
  /// Indices of constrained particles (in the order first constrained).
  const std::vector<int>& constrained() const { return constrained_; }
  /// 0 free, 1 one direction (contact), 3 fixed.
  int num_constrained_directions(int i) const { return kind_[i]; }
  const Eigen::Vector3d& normal(int i) const { return normal_[i]; }

 private:
  std::vector<std::uint8_t> kind_;
  std::vector<Eigen::Vector3d> normal_;
  std::vector<int> constrained_;
  Eigen::VectorXd prescribed_;
};

}  // namespace costume::sim
