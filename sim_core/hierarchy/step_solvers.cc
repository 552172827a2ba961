#include "sim_core/hierarchy/step_solvers.h"

#include "sim_core/hierarchy/hierarchical_solver.h"
#include "sim_core/hierarchy/multigrid_solver.h"

namespace costume::sim {

std::shared_ptr<QuincunxPyramid> MakePyramid(std::shared_ptr<const ClothModel> model,
                                             const StepperSettings& settings) {
  if (settings.method != SolverMethod::kHierarchical &&
      settings.method != SolverMethod::kMultigrid) {
    return nullptr;
  }
  return std::make_shared<QuincunxPyramid>(std::move(model), settings.levels);
}

std::unique_ptr<StepSolver> MakeStepSolver(const ClothModel& model, const StepperSettings& settings,
                                           std::shared_ptr<const QuincunxPyramid> pyramid) {
  switch (settings.method) {
    case SolverMethod::kHierarchical:
      return std::make_unique<HierarchicalSolver>(std::move(pyramid), settings.pcg,
                                                  settings.jacobian, settings.external);
    case SolverMethod::kMultigrid:
      return std::make_unique<MultigridSolver>(std::move(pyramid), settings.pcg,
                                               settings.jacobian, settings.external,
                                               settings.coarse_operator);
    case SolverMethod::kDirect:
      return std::make_unique<DirectStepSolver>(model);
    case SolverMethod::kPcg:
      break;
  }
  return std::make_unique<FlatPcgSolver>(model.num_particles(), settings.pcg);
}

}  // namespace costume::sim
