#pragma once
/// @file
/// Picks the StepSolver a method asks for, building the quincunx pyramid when needed.

#include <memory>

#include "sim_core/hierarchy/quincunx_pyramid.h"
#include "sim_core/solver/implicit_stepper.h"
#include "sim_core/solver/step_solver.h"

namespace costume::sim {

/// The pyramid of `model` with `settings.levels` levels (0 = all), for the hierarchical and
/// multigrid methods; null for flat PCG and CHOLMOD.
std::shared_ptr<QuincunxPyramid> MakePyramid(std::shared_ptr<const ClothModel> model,
                                             const StepperSettings& settings);

/// The solver for settings.method; `pyramid` must be MakePyramid's result.
std::unique_ptr<StepSolver> MakeStepSolver(const ClothModel& model, const StepperSettings& settings,
                                           std::shared_ptr<const QuincunxPyramid> pyramid);

}  // namespace costume::sim
