#pragma once
/// @file
/// Iterations of one implicit step to 1e-6 from SmoothState, for comparing the solvers'
/// preconditioners on one model (the pyramid tests and the MakeHuman garments).

#include <gtest/gtest.h>

#include <memory>

#include "sim_core/hierarchy/step_solvers.h"
#include "sim_core/solver/implicit_stepper.h"
#include "tests/support/smooth_state.h"

namespace costume::test {

/// Iterations `method` (with the coarse operator `coarse` for multigrid) needs for one step of
/// 1/60 s of `model` from SmoothState; a failed expectation when it does not converge.
inline int IterationsOfOneStep(
    sim::SolverMethod method, std::shared_ptr<const sim::ClothModel> model,
    sim::CoarseOperator coarse = sim::CoarseOperator::kRediscretised) {
  sim::StepperSettings settings;
  settings.method = method;
  settings.coarse_operator = coarse;
  settings.pcg.tolerance = 1e-6;
  sim::ImplicitStepper stepper(
      model, settings, sim::MakeStepSolver(*model, settings, sim::MakePyramid(model, settings)));
  sim::ClothState state = SmoothState(*model);  // stretched in plane: every spring works
  const sim::StepReport report = stepper.Step(state, 1.0 / 60.0, {});
  EXPECT_TRUE(report.converged) << sim::SolverMethodName(method);
  return report.iterations;
}

}  // namespace costume::test
