#pragma once
/// @file
/// The designer's grab on the cloth (paper §5; DESIGN.md "Haptic selection and forces"): the
/// device force F_h acts at the centre m of a selection sphere of radius r, and each particle
/// inside it gets F(x) = F_h·g(x) with the isotropic Gaussian g(x) = exp(−‖x − m‖²/(2s)),
/// normalised so g(m) = 1. The paper's printed formula lost its minus sign and gives s = r/2
/// without units; here s is a variance, s = (r/2)² [m²], so the weight falls to
/// e^(−2) ≈ 0.135 at the sphere's edge whatever the radius.

#include <Eigen/Core>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"

namespace costume::sim {

struct Grab {
  /// Sphere centre m, scene frame [m].
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  /// Selection radius r [m] > 0.
  double radius = 0.05;
  /// Device force F_h at the centre, scene frame [N].
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  /// When > 0 [N/m], the grab is a position coupling instead of a force: each grabbed
  /// particle i is pulled by a zero-length spring of stiffness coupling_stiffness·g(x_i)
  /// towards where the sphere's motion since the grab started takes it, solved implicitly.
  /// A haptic device measures position, not force; coupling it by a force computed at 1 kHz
  /// and applied explicitly to grams of cloth at 60 Hz is unstable beyond a few N/m
  /// (h²·k·Σg/m ≫ 1), while the implicit spring is stable at any stiffness. F_h is then
  /// ignored.
  double coupling_stiffness = 0.0;
};

/// Whether every field is finite and the radius positive.
bool IsValidGrab(const Grab& grab);

/// The Gaussian's variance s = (r/2)² [m²] for a selection radius r [m] > 0. The one place
/// the width is chosen: the haptic server uses it too.
inline double GaussianVariance(double radius) { return 0.25 * radius * radius; }

/// g(x) = exp(−‖x − m‖²/(2s)) for point x [m], centre m [m], variance s [m²] > 0 [-].
/// Never throws; never allocates.
double GaussianWeight(const Eigen::Vector3d& x, const Eigen::Vector3d& centre, double variance);

/// g(x) of the grab's sphere: GaussianWeight with s = GaussianVariance(r) [-]. Never throws.
double GrabWeight(const Grab& grab, const Eigen::Vector3d& x);

/// Indices of the rows of `positions` (n×3) [m] within `radius` [m] of `centre` (‖x − m‖ ≤ r),
/// ascending, into `selected` (cleared first). Never throws; allocates only when `selected`
/// grows.
void SelectWithin(const Points& positions, const Eigen::Vector3d& centre, double radius,
                  std::vector<int>& selected);

/// The particles within r of m: what a grab holds from the moment it starts (they stay
/// held as the sphere moves, so the cloth cannot slip out of the hand). Never throws;
/// allocates only when `selected` grows.
void SelectGrabbed(const Grab& grab, const Points& positions, std::vector<int>& selected);

/// F_h·g(x) on each selected particle into `applied` (n×3, zero elsewhere) [N]. Never
/// throws; allocates only when `applied` has the wrong size.
void ApplyGrab(const Grab& grab, const Points& positions, const std::vector<int>& selected,
               Points& applied);

/// The force fed back to the device [N]: the sum of the spring forces (elastic and damping)
/// the rest of the cloth exerts on the selected particles — what the hand holding them feels,
/// pulling back against the grab; minus the force the hand's grab puts into those springs
/// (the "minus the sum" counts the springs' forces from the hand's side). Springs
/// joining two selected particles cancel. Never throws; never allocates.
Eigen::Vector3d GrabFeedback(const ClothModel& model, const ClothState& state,
                             const std::vector<int>& selected, std::vector<char>& is_selected);

}  // namespace costume::sim
