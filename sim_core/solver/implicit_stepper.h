#pragma once
/// @file
/// One backward-Euler step linearised once (Baraff & Witkin 1998, eq. 16–18):
///   (M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f₀ + h ∂f/∂x v₀),  v ← v + Δv,  x ← x + h v,
/// with pins and contacts as filtered velocity constraints (§5), solved by a StepSolver
/// (flat PCG, CHOLMOD, the hierarchical step or multigrid PCG). Forces: springs with axial damping, gravity, linear air drag, and Coulomb
/// friction at contacts, linearised inside the solve (see AddFriction in the .cc).

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"
#include "sim_core/collision/contact.h"
#include "sim_core/solver/constraints.h"
#include "sim_core/solver/solver_method.h"
#include "sim_core/solver/spring_forces.h"
#include "sim_core/solver/step_solver.h"
#include "sim_core/solver/system_matrix.h"

namespace costume::sim {

struct StepperSettings {
  SolverMethod method = SolverMethod::kPcg;
  PcgSettings pcg;
  JacobianMode jacobian = JacobianMode::kDefinite;
  ExternalForces external;
  /// Start PCG from the previous step's Δv (cheap and usually close).
  bool warm_start = true;
  /// Pyramid levels for kHierarchical and kMultigrid, counting level 0; 0 = all.
  int levels = 0;
  /// The multigrid V-cycle's coarse matrices (kMultigrid only).
  CoarseOperator coarse_operator = CoarseOperator::kRediscretised;
};

/// What happened in one step: the solve's report (iterations, residual, converged) plus
/// the step's own flags. Flags instead of exceptions: the step never throws.
struct StepReport : SolveReport {
  /// The step produced a non-finite value, the factorisation failed or h was not a finite
  /// positive number; the state was restored to its value before the step. Remedy: a
  /// smaller step or softer material.
  bool rolled_back = false;
  int num_contacts = 0;
};

/// Largest stiffness ratio h²k/m (step h, stiffest spring k, lightest particle m) the
/// once-linearised step is trusted with. Beyond it a single linearisation can inject energy
/// (a stiff spring swung through a large angle in one step comes out stretched);
/// tests/sim_core/scene/stability_matrix_test.cc measured growth from about 1e7 on.
constexpr double kMaxStiffnessRatio = 1e6;

/// Refuses (InputError naming `context`, the values and the substeps that would do, or that
/// none up to kMaxSubsteps would) a step h [s] whose stiffness ratio for `model` exceeds
/// kMaxStiffnessRatio.
void RequireStableStep(const ClothModel& model, double h, const std::string& context);

/// The stiffness ratio trusted to one step when the strain limit follows it
/// (strain_limit.h), which takes back the stretch that turning stiff springs injects: every
/// fabric preset on the MakeHuman suits' 2 mg particles (h²k/m about 1.4e6 at 60 Hz) runs at
/// one step a frame. Beyond it the stability matrix measured energy gained in the first steps
/// (0.5 J on a 10 g sheet at 1.1e7), so the engine splits the frame instead.
constexpr double kMaxLimitedStiffnessRatio = 1e7;

/// The least number of equal steps of a frame of `frame_time` [s] > 0 with h²k/m at most
/// `max_ratio` for `model`'s stiffest spring on its lightest particle; at least 1. Never
/// throws.
int StepsForStiffness(const ClothModel& model, double frame_time, double max_ratio);

class ImplicitStepper {
 public:
  /// Allocates everything a step needs for `model`. `solver` solves each step's system;
  /// when null, flat PCG or CHOLMOD per settings.method (the hierarchical and multigrid
  /// solvers live in sim_core/hierarchy: MakeStepSolver). Throws InputError for bad settings.
  ImplicitStepper(std::shared_ptr<const ClothModel> model, const StepperSettings& settings,
                  std::unique_ptr<StepSolver> solver = nullptr);
  ~ImplicitStepper();

  /// Advances `state` by h [s] (> 0) with pins held and `contacts` constrained; fills each
  /// contact's normal_impulse. Never throws; allocation-free after the first call.
  StepReport Step(ClothState& state, double h, std::span<Contact> contacts);

  /// The velocity pinned particle `particle` has after the coming steps [m/s]: zero by
  /// default (a pin holds still); a garment attached to a moving body sets it before each
  /// step so the pin lands where the body takes it. Ignored for unpinned particles. Never
  /// throws; never allocates.
  void SetPinVelocity(int particle, const Eigen::Vector3d& velocity) {
    pin_velocity_.row(particle) = velocity.transpose();
  }

  /// Forces applied to the particles in the coming steps (n×3) [N], held by the caller;
  /// null for none. Never throws; never allocates.
  void SetAppliedForces(const Points* forces) { settings_.external.applied = forces; }

  /// Zero-length springs to `targets` (n×3) [m] of stiffness `stiffness` (n) [N/m], held by
  /// the caller, solved implicitly (ExternalForces::anchor_targets); nulls for none. Never
  /// throws; never allocates.
  void SetAnchors(const Points* targets, const Eigen::VectorXd* stiffness) {
    settings_.external.anchor_targets = targets;
    settings_.external.anchor_stiffness = stiffness;
  }

  /// Switches to a revision of the model with the same particles and springs (rest lengths
  /// edited, paper §5.3): the system's pattern and the solver are kept. Throws InputError
  /// when the topology differs.
  void ReplaceModel(std::shared_ptr<const ClothModel> revision);

  const ClothModel& model() const { return *model_; }
  const StepperSettings& settings() const { return settings_; }

 private:
  void AddFriction(const ClothState& state, double h, std::span<const Contact> contacts);
  void SetConstraints(const ClothState& state, std::span<const Contact> contacts);
  bool Solve(const ClothState& state, double h, StepReport& report);
  void StoreContactImpulses(std::span<Contact> contacts) const;

  std::shared_ptr<const ClothModel> model_;
  StepperSettings settings_;
  SystemMatrix a_;
  Constraints constraints_;
  std::unique_ptr<StepSolver> solver_;
  Eigen::VectorXd b_, dv_, a_dv_;
  Eigen::VectorXd spring_rhs_;  // the assembly's scratch: 3 per spring
  Points pin_velocity_;
  ClothState backup_;
};

}  // namespace costume::sim
