#pragma once
/// @file
/// Spring, damping, drag and gravity forces and their Jacobians (DESIGN.md's corrected
/// equation (4); Baraff & Witkin 1998 §4–5). Layout: 3n vectors, particle i at [3i, 3i+3).

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"

namespace costume::sim {

/// How the stiffness Jacobian of a compressed spring (length < rest) is treated.
/// The exact Jacobian k[d̂d̂ᵀ + (1 − L/ℓ)(I − d̂d̂ᵀ)] has a negative transverse term under
/// compression, which makes the system matrix indefinite and CG unreliable. kDefinite drops
/// that term for compressed springs (keeping k d̂d̂ᵀ), as Choi & Ko 2002 and most B&W
/// implementations do: the force stays exact, only the linearisation of a buckling spring is
/// softened, so equilibria are unchanged while the matrix stays positive definite.
enum class JacobianMode { kDefinite, kExact };

/// One spring's force and derivative blocks, seen from its end a (end b gets the negatives).
/// The blocks are kept in their closed form, a multiple of I plus a multiple of d̂d̂ᵀ, so the
/// system's assembly (which runs for every spring of every level every step) writes the six
/// values of the symmetric block without forming 3×3 products.
struct SpringTerms {
  /// Force on particle a [N] (spring plus axial damping).
  Eigen::Vector3d force_on_a;
  /// Unit direction d̂ from a to b (zero for a spring of zero length).
  Eigen::Vector3d direction;
  /// ∂f_a/∂x_b = transverse_stiffness·I + (axial_stiffness − transverse_stiffness)·d̂d̂ᵀ
  /// [N/m]: k along the spring, k(1 − L/ℓ) across it (see JacobianMode).
  double axial_stiffness = 0.0;
  double transverse_stiffness = 0.0;
  /// ∂f_a/∂v_b = damping·d̂d̂ᵀ [N·s/m].
  double damping = 0.0;

  /// ∂f_a/∂x_b [N/m] (= −∂f_a/∂x_a); excludes the damping force's position derivative,
  /// which B&W also drop (it is non-symmetric and small).
  Eigen::Matrix3d df_dx() const;
  /// ∂f_a/∂v_b [N·s/m] (= −∂f_a/∂v_a) = c d̂d̂ᵀ.
  Eigen::Matrix3d df_dv() const;
  /// df_dx() · w without forming the matrix.
  Eigen::Vector3d DfDxTimes(const Eigen::Vector3d& w) const;
};

/// Evaluates one spring. Never throws; never allocates. A spring of zero current length
/// gets zero force and a zero transverse term (its direction is undefined).
SpringTerms EvaluateSpring(const Spring& spring, const Eigen::Vector3d& xa,
                           const Eigen::Vector3d& xb, const Eigen::Vector3d& va,
                           const Eigen::Vector3d& vb, JacobianMode mode);

// Inline: the assembly calls these for every spring of every level every step.
inline SpringTerms EvaluateSpring(const Spring& spring, const Eigen::Vector3d& xa,
                                  const Eigen::Vector3d& xb, const Eigen::Vector3d& va,
                                  const Eigen::Vector3d& vb, JacobianMode mode) {
  SpringTerms t;
  const Eigen::Vector3d d = xb - xa;
  const double length = d.norm();
  if (length <= 0.0) {
    t.force_on_a.setZero();
    t.direction.setZero();
    t.axial_stiffness = t.transverse_stiffness = spring.stiffness;  // k I
    return t;
  }
  t.direction = d / length;
  const double stretch = length - spring.rest_length;
  t.force_on_a =
      (spring.stiffness * stretch + spring.damping * t.direction.dot(vb - va)) * t.direction;
  double transverse = 1.0 - spring.rest_length / length;
  if (mode == JacobianMode::kDefinite && transverse < 0.0) transverse = 0.0;
  t.axial_stiffness = spring.stiffness;
  t.transverse_stiffness = spring.stiffness * transverse;
  t.damping = spring.damping;
  return t;
}

inline Eigen::Matrix3d SpringTerms::df_dx() const {
  return transverse_stiffness * Eigen::Matrix3d::Identity() +
         (axial_stiffness - transverse_stiffness) * direction * direction.transpose();
}

inline Eigen::Matrix3d SpringTerms::df_dv() const {
  return damping * direction * direction.transpose();
}

inline Eigen::Vector3d SpringTerms::DfDxTimes(const Eigen::Vector3d& w) const {
  return transverse_stiffness * w +
         ((axial_stiffness - transverse_stiffness) * direction.dot(w)) * direction;
}

/// External force settings shared by every particle.
struct ExternalForces {
  /// Gravity [m/s²].
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, -9.81, 0.0);
  /// Whether each particle feels its linear air drag −model.drag()[i]·v_i.
  bool air_drag = true;
  /// Force applied to each particle (n×3) [N], held by the caller: the designer's grab
  /// (paper §5); null for none.
  const Points* applied = nullptr;
  /// Zero-length springs pulling particle i towards anchor_targets row i with stiffness
  /// anchor_stiffness[i] [N/m] (0: none), held by the caller and solved implicitly like the
  /// cloth's own springs, so a stiff grab stays stable on light cloth; null for none.
  const Points* anchor_targets = nullptr;
  const Eigen::VectorXd* anchor_stiffness = nullptr;
};

/// Total force (3n) [N] on every particle: springs, damping, gravity, drag, applied forces.
/// Test and tool path (allocates).
Eigen::VectorXd ComputeForces(const ClothModel& model, const ClothState& state,
                              const ExternalForces& external);

/// ∂f/∂x and ∂f/∂v (3n×3n) as sparse matrices. Test and tool path (allocates).
void ComputeForceJacobians(const ClothModel& model, const ClothState& state,
                           const ExternalForces& external, JacobianMode mode,
                           Eigen::SparseMatrix<double>* df_dx, Eigen::SparseMatrix<double>* df_dv);

/// Kinetic + spring + gravitational potential energy [J] (gravity potential −m g·x).
double MechanicalEnergy(const ClothModel& model, const ClothState& state,
                        const Eigen::Vector3d& gravity);

/// Structural strain statistics over structural springs, strain = length / rest − 1:
/// the largest stretch, the mean of |strain| (stretch and compression alike), and the
/// spring that has the largest (index into ClothModel::springs(); -1 when none stretches).
struct StrainStats {
  double max = 0.0;
  double mean = 0.0;
  int max_spring = -1;
};
StrainStats StructuralStrain(const ClothModel& model, const Points& positions);

}  // namespace costume::sim
