#pragma once
/// @file
/// Strain limiting after the implicit step (Provot 1995, the paper's [Pro95], with a target
/// of the step's own): the springs that carry the fabric's stretch and shear are shortened
/// back to the length the step meant them to have, in Gauss-Seidel sweeps that keep the
/// cloth outside the obstacles' shells.
///
/// Why the step's own target: one backward-Euler step linearised once moves each spring's
/// ends along straight lines, so a spring that turns through an angle θ within the step comes
/// out longer by about ℓθ²/2 than the step meant, however stiff it is. At a woven fabric's
/// measured stiffness (10 kN/m) that stretch is nearly all there is: on the built-in skirt
/// walking in cotton, CHOLMOD's exact solve meant at most 1.1 % strain and delivered up to
/// 22 %; the default PCG delivered 95 %. The length the step meant is its first-order length
/// u₀·d₁ (d₁ the spring after the step, u₀ its direction before). A spring longer than that
/// (or than its rest length, where the step meant compression) by more than kFreeStretch is
/// cut back to it, so the fabric's elastic stretch, which the step meant, is kept: a strip
/// under a load stretches by F/k as without the limit. Structural springs are also held to
/// (1 + limit)·rest whatever the step meant (a loose solve, a grab beyond what the fabric
/// takes); shear springs are not (woven fabric shears far on the bias).
///
/// Why planes: the obstacles' position corrections come after the limit, and a particle the
/// body pushes out by a few millimetres with its neighbours left behind stretches its springs
/// by tens of per cent (the body's correction alone took the walking skirt's largest strain
/// from 1 % to 20 %). The sweeps instead keep each listed particle on the outer side of a
/// plane (the contact's shell, or where the body's correction would move it), so the
/// springs and the body agree before the correction runs.
///
/// Why tethers: Gauss-Seidel sweeps bring a chain of n over-stretched springs back in about n²
/// sweeps, so a load pulling a whole garment down from its waistband (a hard grab, a jump's
/// landing) was still 34 % long at the top after 64 sweeps where the cap is 10 %. Each
/// unpinned particle is also kept within (1 + limit) times its rest distance along the
/// structural springs from the nearest pinned particle (a long-range attachment, as Unreal's
/// Chaos Cloth and Jolt do): implied by the springs' own caps, so it forbids nothing they
/// allow, and one projection per particle does what the chain's sweeps cannot.
///
/// The ends of a shortened spring stop separating along it (an inelastic impulse, momentum
/// kept, kinetic energy only lost); Provot's velocity update, correction / h, cost the solve
/// a third more iterations in the next steps.

#include <span>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"
#include "sim_core/collision/contact.h"

namespace costume::sim {

/// A spring is left alone until it is longer than its target by this much of its rest
/// length [-]: the step's second-order stretch below it is a fraction of a millimetre on a
/// garment's springs, and cutting it too cost the solve more iterations than it saved.
inline constexpr double kFreeStretch = 0.01;

/// How far the sweeps go.
struct StrainLimitSettings {
  /// Largest strain [-] a structural spring keeps whatever the step meant (0.1 = 10 %), > 0.
  double limit = 0.1;
  /// Sweeps stop once no spring is longer than its target by more than this fraction of its
  /// rest length [-].
  double tolerance = 2e-3;
  /// Most sweeps a call makes.
  int max_sweeps = 64;
};

/// What a call did.
struct StrainLimitReport {
  int sweeps = 0;
  /// Springs shortened, summed over the sweeps.
  int corrections = 0;
  /// Largest excess over its target [-] (of the rest length) left after the last sweep.
  double remaining = 0.0;
};

/// A particle kept on the outer side of the plane normal·x = offset: normal·x >= offset.
struct ShellPlane {
  int particle = 0;
  /// Unit normal pointing out of the obstacle [-].
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
  /// [m]
  double offset = 0.0;
};

/// The strain limit of one model's topology, with its memory preallocated.
class StrainLimiter {
 public:
  /// Lists `model`'s structural and shear springs, and each unpinned particle's tether: the
  /// pinned particle nearest along the structural springs (Dijkstra over their rest lengths)
  /// and that distance. Springs' rest lengths are read at each call; the tethers' are those of
  /// `model`, so a revision with edited rest lengths needs a new limiter.
  explicit StrainLimiter(const ClothModel& model);

  /// Remembers each limited spring's direction at the start of the step (`positions` n×3
  /// [m]) and drops the last step's planes. Never throws; never allocates after the first
  /// call.
  void BeginStep(const Points& positions);

  /// After the solve: each limited spring's target from the solved `positions` (the length
  /// the step meant, at least the rest length, plus kFreeStretch; structural springs at most
  /// (1 + settings.limit)·rest). Never throws; never allocates.
  void SetTargets(const ClothModel& model, const StrainLimitSettings& settings,
                  const Points& positions);

  /// Targets of the cap alone: (1 + settings.limit)·rest for structural springs, none for
  /// shear springs. For a limit after something other than the step moved the cloth
  /// (self-collision's impulses), whose moves are no stretch the step meant and no artefact
  /// of it either: only what goes past the cap is taken back. Never throws; never allocates.
  void SetCapTargets(const ClothModel& model, const StrainLimitSettings& settings);

  /// Adds a plane for each contact that has one (Contact::shell_offset), and `planes`.
  /// Never throws; allocates only when the list grows past its size so far.
  void AddPlanes(std::span<const Contact> contacts);
  void AddPlanes(std::span<const ShellPlane> planes);

  /// Sweeps until every limited spring is within settings.tolerance of its target (or
  /// settings.max_sweeps): each longer one is shortened to its target, the correction split
  /// by inverse mass (pinned particles and those `fixed` marks, n flags or empty, do not
  /// move), and the particles with planes are kept outside them. Never throws; never
  /// allocates after the first call.
  StrainLimitReport Limit(const ClothModel& model, const StrainLimitSettings& settings,
                          ClothState& state, const std::vector<char>& fixed = {});

 private:
  std::vector<int> spring_, a_, b_;
  std::vector<char> structural_;
  /// Each limited spring's direction at the step's start, its rest and target lengths [m].
  Points start_direction_;
  std::vector<double> rest_, target_;
  /// Inverse masses [1/kg] of this call (0: does not move).
  std::vector<double> w_;
  std::vector<ShellPlane> planes_;
  /// Tethers: particle, its pinned anchor, and their rest distance along the cloth [m].
  struct Tether {
    int particle;
    int anchor;
    double rest;
  };
  std::vector<Tether> tethers_;
};

}  // namespace costume::sim
