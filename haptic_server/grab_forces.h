#pragma once
/// @file
/// Haptic selection and forces (paper §5; DESIGN.md "Haptic selection and forces").
///
/// Gaussian. g(x) = exp(−‖x − m‖² / (2 s)), g(m) = 1, with s a *variance* [m²]. DESIGN.md
/// prints s = r/2, which mixes units (a length where a squared length belongs). We settle on
/// s = (r/2)²: the standard deviation is half the sphere radius, so a particle at the sphere's
/// rim gets g = exp(−2) ≈ 0.135 and the weights fall smoothly to near zero at the selection
/// boundary instead of jumping there.
///
/// Grab force (simulation side, 60 Hz): each particle within r of m gets F(x) = F_h · g(x).
///
/// Feedback (haptic side, 1 kHz): the force the cloth exerts on the hand, the sum over the
/// selected particles of the spring forces (Hooke + damping along each spring) acting on them.
/// Sign: the issue writes "minus the sum of the spring forces"; minus applies to the force the
/// hand exerts on the cloth (at equilibrium F_h Σg = −Σ f_spring). The device must render the
/// reaction, +Σ f_spring, which points back towards the cloth's rest shape: pull the cloth in
/// +x and the device pulls the hand towards −x. Rendering −Σ f_spring would push the hand
/// further along its pull (positive feedback, unstable), so we do not.
/// Springs with both ends selected cancel in the sum (equal and opposite) and are skipped:
/// only boundary springs, one end in the sphere, contribute.
///
/// Between simulation frames (60 Hz) the tick moves the selected particles with the tip,
/// x_i + g(x_i) · u where u is the tip's scene displacement since the patch was captured (the
/// "local model" of multi-rate haptics): the feedback then changes at 1 kHz with the hand, and
/// its stiffness is what force_safety.h limits.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/scene/grab.h"

namespace costume::haptics {

/// The Gaussian and the selection are the simulation's own (sim_core/scene/grab.h), so the
/// device and the cloth always agree on which particles a grab holds and how much:
/// GaussianVariance(r) = (r/2)² [m²], GaussianWeight(x, m, s), and SelectParticles = the
/// particles within r of m, ascending.
using sim::GaussianVariance;
using sim::GaussianWeight;
inline void SelectParticles(const sim::Points& positions, const Eigen::Vector3d& centre,
                            double radius, std::vector<int>& selected) {
  sim::SelectWithin(positions, centre, radius, selected);
}

/// Adds F(x_i) = F_h · g(x_i) to row i of `forces` (n×3) [N] for every i in `selected`, with
/// g centred at `centre` [m] with variance GaussianVariance(radius). `device_force` F_h [N] is
/// in the scene frame. Never throws; never allocates.
void AddGrabForces(const sim::Points& positions, const std::vector<int>& selected,
                   const Eigen::Vector3d& centre, double radius,
                   const Eigen::Vector3d& device_force, sim::Points& forces);

/// A spring of the patch, between local particle indices a != b.
struct PatchSpring {
  int a = 0;
  int b = 0;
  /// Stiffness [N/m] >= 0.
  double stiffness = 0.0;
  /// Damping along the spring [N·s/m] >= 0.
  double damping = 0.0;
  /// Rest length [m] > 0.
  double rest_length = 0.0;
};

/// The haptic tick's local copy of the cloth near the grab, refreshed at each simulation frame.
/// Filled by the I/O thread (from the simulation's patch message) in a TripleBuffer slot,
/// then PreparePatch, then published; the tick only reads it.
struct HapticPatch {
  /// Simulation frame this copy comes from (0: no patch yet).
  std::uint64_t sequence = 0;
  /// When the patch arrived, on the haptic loop's clock [s] (staleness is measured from it).
  double arrival_time = 0.0;
  /// Grab sphere centre m when the patch was captured, scene frame [m].
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  /// Grab sphere radius r [m] > 0.
  double radius = 0.05;
  /// Particle positions, scene frame [m] (local indices 0..n-1).
  std::vector<Eigen::Vector3d> positions;
  /// Particle velocities, scene frame [m/s] (same length as positions).
  std::vector<Eigen::Vector3d> velocities;
  /// Springs between the patch's particles (indices into positions).
  std::vector<PatchSpring> springs;

  // ---- derived by PreparePatch, read by the tick --------------------------------------------
  /// g(x_i) for selected particles (‖x_i − m‖ ≤ r), 0 otherwise (length n).
  std::vector<double> weights;
  /// Springs with exactly one selected end: index into springs, and +1 when end a is the
  /// selected one, −1 when end b is.
  std::vector<std::int32_t> boundary_springs;
  std::vector<std::int8_t> boundary_signs;
  /// Number of selected particles.
  int num_selected = 0;
  /// False when any position, velocity or spring parameter is not finite or a spring index is
  /// out of range; the tick then renders no force and counts it.
  bool valid = false;

  /// Reserves room for `num_particles` and `num_springs` so that filling and preparing a patch
  /// of at most that size never allocates.
  void Reserve(int num_particles, int num_springs);
};

/// Computes the derived fields of `patch` (weights, boundary springs, num_selected, valid) from
/// its centre, radius, positions and springs. Runs on the I/O thread; never throws; allocates
/// only beyond the reserved capacity.
void PreparePatch(HapticPatch& patch);

/// The force the cloth exerts on the hand [N], scene frame: Σ over boundary springs of the
/// spring force (Hooke + damping along the spring) on their selected end, with the selected
/// particles displaced by g(x_i) · `tip_displacement` (scene [m], tip position now minus
/// patch.centre). Zero when the patch is invalid or selects nothing. A result that is not
/// finite is returned as is (the caller's safety layer handles it).
/// Cost O(number of boundary springs). Never throws; never allocates.
Eigen::Vector3d FeedbackForce(const HapticPatch& patch, const Eigen::Vector3d& tip_displacement);

}  // namespace costume::haptics
