// The implicit step against closed-form results: the discrete backward-Euler oscillator,
// energy decay, pins, determinism, and agreement of PCG with the direct solver.
#include "sim_core/solver/implicit_stepper.h"

#include <gtest/gtest.h>

#include <Eigen/QR>

#include <cmath>
#include <complex>
#include <cstring>
#include <numbers>
#include <vector>

#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"
#include "tests/support/test_scenes.h"

namespace costume::sim {
namespace {

/// One particle (mass m) on a spring (k, c, rest 1 m) to a pinned particle, along x.
std::shared_ptr<const ClothModel> Oscillator(double k, double m, double c) {
  ClothModelData data;
  data.rest_positions.resize(2, 3);
  data.rest_positions << 0, 0, 0, 1, 0, 0;
  data.masses = Eigen::Vector2d(1.0, m);
  data.areas = Eigen::Vector2d::Zero();
  data.springs.push_back({0, 1, SpringKind::kStructural, k, c, 1.0});
  data.pinned = {0};
  return ClothModel::Create(data);
}

StepperSettings Weightless(SolverMethod method) {
  StepperSettings settings;
  settings.method = method;
  settings.external.gravity.setZero();
  settings.pcg.tolerance = 1e-12;
  return settings;
}

/// Closed form of backward Euler on x'' = −ω²x − γx' (derived independently of the code):
/// [x₁, v₁] solves [[1, −h], [hω², 1 + hγ]]·[x₁, v₁] = [x₀, v₀]; the eigenvalues of that
/// matrix are μ = 1 + hγ/2 ± i·sqrt(1 + hγ + h²ω² − (1 + hγ/2)²), the step multiplies each
/// mode by 1/μ: |1/μ| per step, and turns it by arg μ, so ω_h = arg μ / h.
struct DiscreteOscillator {
  double angular_frequency;  // rad/s
  double decay_per_step;     // amplitude factor
};
DiscreteOscillator BackwardEulerOscillator(double k, double m, double c, double h) {
  const double w2 = k / m, g = c / m;
  const std::complex<double> mu(1 + h * g / 2, std::sqrt(1 + h * g + h * h * w2 -
                                                         (1 + h * g / 2) * (1 + h * g / 2)));
  return {std::arg(mu) / h, 1.0 / std::abs(mu)};
}

/// Runs the oscillator from a 1 mm stretch; returns the displacement after each step.
std::vector<double> Trajectory(double k, double m, double c, double h, int steps,
                               SolverMethod method) {
  const auto model = Oscillator(k, m, c);
  ImplicitStepper stepper(model, Weightless(method));
  ClothState state = ClothState::AtRest(*model);
  state.positions(1, 0) = 1.001;
  std::vector<double> x{1e-3};
  for (int s = 0; s < steps; ++s) {
    stepper.Step(state, h, {});
    x.push_back(state.positions(1, 0) - 1.0);
  }
  return x;
}

/// Frequency from successive maxima (each refined by a parabola), for finely sampled runs.
double FrequencyFromPeaks(const std::vector<double>& x, double h) {
  std::vector<double> times;
  for (std::size_t s = 1; s + 1 < x.size(); ++s) {
    if (x[s] > x[s - 1] && x[s] >= x[s + 1]) {
      const double denom = x[s - 1] - 2 * x[s] + x[s + 1];
      times.push_back((s + 0.5 * (x[s - 1] - x[s + 1]) / denom) * h);
    }
  }
  EXPECT_GE(times.size(), 3u);
  return 2 * std::numbers::pi * (times.size() - 1) / (times.back() - times.front());
}

/// The trajectory of a linear two-state map obeys x[n+1] = p·x[n] + q·x[n−1] with
/// p = 2|λ|cos θ, q = −|λ|² for its eigenvalues λ = |λ|e^{±iθ}. Least squares for (p, q)
/// recovers the per-step decay |λ| and the frequency θ/h from the samples alone.
DiscreteOscillator FitLinearRecurrence(const std::vector<double>& x, double h) {
  Eigen::MatrixX2d lhs(x.size() - 2, 2);
  Eigen::VectorXd rhs(x.size() - 2);
  for (std::size_t n = 1; n + 1 < x.size(); ++n) {
    lhs.row(n - 1) << x[n], x[n - 1];
    rhs[n - 1] = x[n + 1];
  }
  const Eigen::Vector2d pq = lhs.colPivHouseholderQr().solve(rhs);
  const double modulus = std::sqrt(-pq[1]);
  return {std::acos(pq[0] / (2 * modulus)) / h, modulus};
}

TEST(ImplicitStepper, UndampedSpringOscillatesAtSqrtKOverMAsStepShrinks) {
  const double k = 100.0, m = 0.01;  // ω = 100 rad/s
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kDirect}) {
    const double w = FrequencyFromPeaks(Trajectory(k, m, 0.0, 1e-4, 4000, method), 1e-4);
    EXPECT_NEAR(w, std::sqrt(k / m), 0.002 * std::sqrt(k / m)) << SolverMethodName(method);
  }
}

TEST(ImplicitStepper, OscillatorFrequencyAndDampingMatchBackwardEulerClosedForm) {
  const double k = 100.0, m = 0.01;
  for (double c : {0.0, 0.02}) {
    for (double h : {1e-3, 5e-3}) {
      const auto expected = BackwardEulerOscillator(k, m, c, h);
      const auto [w, decay] =
          FitLinearRecurrence(Trajectory(k, m, c, h, 40, SolverMethod::kPcg), h);
      EXPECT_NEAR(w, expected.angular_frequency, 1e-6 * expected.angular_frequency)
          << "c=" << c << " h=" << h;
      EXPECT_NEAR(decay, expected.decay_per_step, 1e-7) << "c=" << c << " h=" << h;
      // The discrete frequency is below √(k/m) and the motion decays: B-E's damping.
      EXPECT_LT(w, std::sqrt(k / m));
      EXPECT_LT(decay, 1.0);
    }
  }
}

TEST(ImplicitStepper, EnergyNeverGrowsWithoutInput) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kDirect}) {
    SceneDescription scene = test::HangScene(9);
    scene.solver.method = method;
    scene.solver.tolerance = 1e-10;
    auto sim = Simulation::Build(scene);
    double energy = MechanicalEnergy(sim->model(), sim->state(), scene.gravity);
    double worst_growth = -1e300;
    for (int f = 0; f < 240; ++f) {
      sim->AdvanceFrame();
      const double next = MechanicalEnergy(sim->model(), sim->state(), scene.gravity);
      worst_growth = std::max(worst_growth, next - energy);
      energy = next;
    }
    // Round-off allowance: 1e-12 J on energies of order 0.1 J.
    EXPECT_LE(worst_growth, 1e-12) << SolverMethodName(method);
  }
}

TEST(ImplicitStepper, PinnedParticlesDoNotMove) {
  auto sim = Simulation::Build(test::HangScene(9));
  const Points rest = sim->state().positions;
  for (int f = 0; f < 30; ++f) sim->AdvanceFrame();
  for (int pin : sim->model().pinned()) {
    EXPECT_EQ((sim->state().positions.row(pin) - rest.row(pin)).norm(), 0.0);
  }
  EXPECT_EQ(sim->model().pinned().size(), 2u);
}

TEST(ImplicitStepper, IdenticalInputsGiveBitIdenticalResults) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kDirect}) {
    SceneDescription scene = test::DrapeScene(17);
    scene.solver.method = method;
    auto first = Simulation::Build(scene);
    auto second = Simulation::Build(scene);
    for (int f = 0; f < 60; ++f) {
      first->AdvanceFrame();
      second->AdvanceFrame();
    }
    const auto& a = first->state();
    const auto& b = second->state();
    EXPECT_EQ(std::memcmp(a.positions.data(), b.positions.data(), a.positions.size() * 8), 0);
    EXPECT_EQ(std::memcmp(a.velocities.data(), b.velocities.data(), a.velocities.size() * 8), 0);
  }
}

TEST(ImplicitStepper, TightPcgAgreesWithDirectSolve) {
  SceneDescription scene = test::HangScene(17);
  scene.solver.tolerance = 1e-10;
  scene.solver.max_iterations = 100000;
  auto pcg = Simulation::Build(scene);
  scene.solver.method = SolverMethod::kDirect;
  auto direct = Simulation::Build(scene);
  for (int f = 0; f < 30; ++f) {
    pcg->AdvanceFrame();
    direct->AdvanceFrame();
  }
  const double difference = (pcg->state().positions - direct->state().positions).cwiseAbs().maxCoeff();
  EXPECT_LT(difference, 1e-6);  // m
}

// h²k/m bounds the step: h = 0.1 s, m = 1 g. k = 1e4 N/m gives 1e5 (allowed); k = 1e6 N/m
// gives 1e7, so h must shrink by sqrt(10) = 3.16: 4 substeps. At k = 1e308 N/m no number of
// substeps up to the allowed 1000 will do, and the message says so (it used to print an
// overflowed int, "multiply solver.substeps by -2147483648").
TEST(RequireStableStep, NamesTheSubstepsNeededOrThatNoneWouldDo) {
  EXPECT_NO_THROW(RequireStableStep(*Oscillator(1e4, 1e-3, 0.0), 0.1, "s.toml"));
  auto message = [](double k) {
    try {
      RequireStableStep(*Oscillator(k, 1e-3, 0.0), 0.1, "s.toml");
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  const std::string stiff = message(1e6);
  EXPECT_NE(stiff.find("s.toml: step h = 0.1 s"), std::string::npos) << stiff;
  EXPECT_NE(stiff.find("h²k/m = 1e+07"), std::string::npos) << stiff;
  EXPECT_NE(stiff.find("multiply solver.substeps by 4,"), std::string::npos) << stiff;
  const std::string absurd = message(1e308);
  EXPECT_NE(absurd.find("more substeps than the 1000 allowed"), std::string::npos) << absurd;
  EXPECT_EQ(absurd.find("-2147483648"), std::string::npos) << absurd;
}

TEST(ImplicitStepper, RefusesNonPositiveStepWithoutTouchingState) {
  auto model = Oscillator(100, 0.01, 0);
  ImplicitStepper stepper(model, Weightless(SolverMethod::kPcg));
  ClothState state = ClothState::AtRest(*model);
  for (double h : {0.0, -1.0, std::nan("")}) {
    const StepReport report = stepper.Step(state, h, {});
    EXPECT_TRUE(report.rolled_back);
    EXPECT_EQ(state.time, 0.0);
  }
}

}  // namespace
}  // namespace costume::sim
