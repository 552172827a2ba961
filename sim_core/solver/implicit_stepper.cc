#include "sim_core/solver/implicit_stepper.h"

#include <algorithm>
#include <cmath>

#include "sim_core/common/input_error.h"
#include "sim_core/solver/implicit_system.h"

namespace costume::sim {

const char* SolverMethodName(SolverMethod method) {
  switch (method) {
    case SolverMethod::kPcg: return "pcg";
    case SolverMethod::kHierarchical: return "hierarchical";
    case SolverMethod::kMultigrid: return "multigrid";
    case SolverMethod::kDirect: return "direct";
  }
  return "unknown";
}

const char* CoarseOperatorName(CoarseOperator coarse) {
  return coarse == CoarseOperator::kGalerkin ? "galerkin" : "rediscretised";
}

void RequireStableStep(const ClothModel& model, double h, const std::string& context) {
  double k_max = 0.0;
  for (const Spring& s : model.springs()) k_max = std::max(k_max, s.stiffness);
  const double m_min = model.masses().minCoeff();
  const double ratio = h * h * k_max / m_min;
  if (ratio <= kMaxStiffnessRatio) return;
  const double longest = std::sqrt(kMaxStiffnessRatio * m_min / k_max);
  // As a double: the factor overflowed an int for a damaged file's 1e308 N/m ("multiply
  // solver.substeps by -2147483648").
  const double factor = std::ceil(h / longest);
  const std::string remedy =
      factor <= kMaxSubsteps
          ? "multiply solver.substeps by " + FormatValue(factor) + ", or use"
          : "more substeps than the " + std::to_string(kMaxSubsteps) + " allowed would be "
            "needed (" + FormatValue(factor) + " times as many): use";
  throw InputError(context + ": step h = " + FormatValue(h) + " s is too long for springs of k = " +
                   FormatValue(k_max) + " N/m on particles of m = " + FormatValue(m_min) +
                   " kg: h²k/m = " + FormatValue(ratio) + " exceeds " +
                   FormatValue(kMaxStiffnessRatio) +
                   ", beyond which one linearisation per step can inject energy. Allowed: "
                   "h <= " + FormatValue(longest) + " s: " + remedy +
                   " a softer material or heavier particles");
}

int StepsForStiffness(const ClothModel& model, double frame_time, double max_ratio) {
  double k_max = 0.0;
  for (const Spring& s : model.springs()) k_max = std::max(k_max, s.stiffness);
  const double m_min = model.masses().minCoeff();
  if (!(k_max > 0.0)) return 1;
  const double longest = std::sqrt(max_ratio * m_min / k_max);
  const double steps = std::ceil(frame_time / longest);
  // As a double first: a damaged file's 1e308 N/m would overflow an int.
  return steps <= 1.0 ? 1 : steps >= 1e9 ? 1000000000 : static_cast<int>(steps);
}

ImplicitStepper::ImplicitStepper(std::shared_ptr<const ClothModel> model,
                                 const StepperSettings& settings,
                                 std::unique_ptr<StepSolver> solver)
    : model_(std::move(model)),
      settings_(settings),
      a_(*model_),
      constraints_(model_->num_particles()),
      solver_(std::move(solver)) {
  RequireInRange("solver.tolerance", settings.pcg.tolerance, 1e-300, 1.0, "");
  RequireInRange("solver.max_iterations", settings.pcg.max_iterations, 1, 1e6, "");
  for (int c = 0; c < 3; ++c) RequireFinite("gravity", settings.external.gravity[c], "m/s²");
  const int n3 = 3 * model_->num_particles();
  b_ = Eigen::VectorXd::Zero(n3);
  dv_ = Eigen::VectorXd::Zero(n3);
  a_dv_ = Eigen::VectorXd::Zero(n3);
  spring_rhs_ = Eigen::VectorXd::Zero(3 * model_->num_springs());
  pin_velocity_ = Points::Zero(model_->num_particles(), 3);
  if (!solver_ && settings.method == SolverMethod::kDirect) {
    solver_ = std::make_unique<DirectStepSolver>(*model_);
  } else if (!solver_) {
    solver_ = std::make_unique<FlatPcgSolver>(model_->num_particles(), settings.pcg);
  }
}

ImplicitStepper::~ImplicitStepper() = default;

// Coulomb friction, regularised and implicit. Applied after the solve, friction would undo
// velocity changes the stiff solve counted on for the neighbours and freeze stretch into the
// cloth; inside the solve it is a tangential damper c = μ F_n / max(|v_t|, v_slip) with F_n
// the previous step's normal force: below v_slip it holds the particle (static friction up to
// μ F_n), above it it resists with μ F_n (kinetic). Implicit, so stable for any c.
void ImplicitStepper::AddFriction(const ClothState& state, double h,
                                  std::span<const Contact> contacts) {
  constexpr double kSlipSpeed = 1e-3;  // m/s: slower counts as sticking
  for (const Contact& c : contacts) {
    if (c.friction <= 0.0 || c.previous_normal_impulse <= 0.0) continue;
    const Eigen::Vector3d v = state.velocities.row(c.particle).transpose();
    const Eigen::Matrix3d tangent = Eigen::Matrix3d::Identity() - c.normal * c.normal.transpose();
    const Eigen::Vector3d v_t = tangent * v;
    const double normal_force = c.previous_normal_impulse / h;
    const double damping = c.friction * normal_force / std::max(v_t.norm(), kSlipSpeed);
    a_.AddToDiagonal(c.particle, (h * damping) * tangent);
    b_.segment<3>(3 * c.particle) -= (h * damping) * v_t;
  }
}

void ImplicitStepper::SetConstraints(const ClothState& state, std::span<const Contact> contacts) {
  constraints_.Clear();
  for (const Contact& c : contacts) {
    const double current = state.velocities.row(c.particle).dot(c.normal);
    constraints_.ConstrainNormal(c.particle, c.normal, c.target_normal_velocity - current);
  }
  // Pins last: they override contacts. A pin moves at its prescribed velocity (Δv = v_pin
  // − v), zero unless the pin is attached to a moving body.
  for (int i : model_->pinned()) {
    constraints_.Fix(i, (pin_velocity_.row(i) - state.velocities.row(i)).transpose());
  }
}

void ImplicitStepper::ReplaceModel(std::shared_ptr<const ClothModel> revision) {
  bool same = revision && revision->num_particles() == model_->num_particles() &&
              revision->num_springs() == model_->num_springs() &&
              revision->pinned() == model_->pinned();
  for (int k = 0; same && k < model_->num_springs(); ++k) {
    same = revision->springs()[k].a == model_->springs()[k].a &&
           revision->springs()[k].b == model_->springs()[k].b;
  }
  if (!same) {
    throw InputError("model '" + model_->name() + "': a revision must keep the particles, " +
                     "springs and pins (only rest lengths may change)");
  }
  model_ = std::move(revision);
}

bool ImplicitStepper::Solve(const ClothState& state, double h, StepReport& report) {
  if (!settings_.warm_start) dv_.setZero();
  static_cast<SolveReport&>(report) = solver_->Solve(state, h, a_, b_, constraints_, dv_);
  return report.solved;
}

void ImplicitStepper::StoreContactImpulses(std::span<Contact> contacts) const {
  // The constraint impulse is what the solve added beyond the unconstrained equation:
  // λ = A Δv − b (momentum units, N·s).
  for (Contact& c : contacts) {
    const int i = c.particle;
    c.normal_impulse = (a_dv_.segment<3>(3 * i) - b_.segment<3>(3 * i)).dot(c.normal);
  }
}

StepReport ImplicitStepper::Step(ClothState& state, double h, std::span<Contact> contacts) {
  StepReport report;
  if (!(h > 0.0 && std::isfinite(h))) {  // a caller bug; refuse without touching the state
    report.rolled_back = true;
    return report;
  }
  report.num_contacts = static_cast<int>(contacts.size());
  backup_ = state;
  SetConstraints(state, contacts);
  AssembleImplicitSystem(*model_, state, h, settings_.jacobian, settings_.external, a_, b_,
                         spring_rhs_, settings_.pcg.pool);
  AddFriction(state, h, contacts);
  const bool solved = Solve(state, h, report);
  if (solved && !contacts.empty()) {
    a_.Multiply(dv_, a_dv_);
    StoreContactImpulses(contacts);
  }
  const int n3 = 3 * model_->num_particles();
  Eigen::Map<Eigen::VectorXd> v(state.velocities.data(), n3);
  Eigen::Map<Eigen::VectorXd> x(state.positions.data(), n3);
  v += dv_;
  x += h * v;
  state.time += h;
  if (!solved || !x.allFinite() || !v.allFinite()) {
    state = backup_;
    dv_.setZero();
    report.rolled_back = true;
  }
  return report;
}

}  // namespace costume::sim
