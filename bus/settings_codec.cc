#include "bus/settings_codec.h"

#include <string>

#include "sim_core/common/input_error.h"

namespace costume::bus {
namespace {

using P = costume_lcm::solver_parameters;

std::int8_t MethodOf(sim::SolverMethod method) {
  switch (method) {
    case sim::SolverMethod::kPcg: return P::METHOD_PCG;
    case sim::SolverMethod::kHierarchical: return P::METHOD_HIERARCHICAL;
    case sim::SolverMethod::kMultigrid: return P::METHOD_MULTIGRID;
    case sim::SolverMethod::kDirect: return P::METHOD_DIRECT;
  }
  return P::METHOD_PCG;
}

sim::SolverMethod MethodFrom(std::int8_t method) {
  switch (method) {
    case P::METHOD_PCG: return sim::SolverMethod::kPcg;
    case P::METHOD_HIERARCHICAL: return sim::SolverMethod::kHierarchical;
    case P::METHOD_MULTIGRID: return sim::SolverMethod::kMultigrid;
    case P::METHOD_DIRECT: return sim::SolverMethod::kDirect;
    default: break;
  }
  throw sim::InputError("command SET_SOLVER: solver.method = " + std::to_string(method) +
                        ": must be 0 (pcg), 1 (hierarchical), 2 (multigrid) or 3 (direct)");
}

std::int8_t CoarseOperatorOf(sim::CoarseOperator op) {
  return op == sim::CoarseOperator::kGalerkin ? P::COARSE_GALERKIN : P::COARSE_REDISCRETISED;
}

sim::CoarseOperator CoarseOperatorFrom(std::int8_t op) {
  switch (op) {
    case P::COARSE_REDISCRETISED: return sim::CoarseOperator::kRediscretised;
    case P::COARSE_GALERKIN: return sim::CoarseOperator::kGalerkin;
    default: break;
  }
  throw sim::InputError("command SET_SOLVER: solver.coarse_operator = " + std::to_string(op) +
                        ": must be 0 (rediscretised) or 1 (galerkin)");
}

using CP = costume_lcm::collision_parameters;

sim::BodyCollisionMethod CollisionMethodFrom(std::int8_t method) {
  switch (method) {
    case CP::METHOD_SUPERQUADRIC: return sim::BodyCollisionMethod::kSuperquadric;
    case CP::METHOD_MESH: return sim::BodyCollisionMethod::kMesh;
    default: break;
  }
  throw sim::InputError("command SET_COLLISION: collision.method = " + std::to_string(method) +
                        ": must be 0 (superquadric) or 1 (mesh)");
}

}  // namespace

costume_lcm::solver_parameters ToMessage(const sim::SolverSettings& settings) {
  costume_lcm::solver_parameters p{};
  p.method = MethodOf(settings.method);
  p.coarse_operator = CoarseOperatorOf(settings.coarse_operator);
  p.levels = settings.levels;
  p.tolerance = settings.tolerance;
  p.max_iterations = settings.max_iterations;
  p.substeps = settings.substeps;
  p.strain_limit = settings.strain_limit;
  return p;
}

sim::SolverSettings FromMessage(const costume_lcm::solver_parameters& solver) {
  sim::SolverSettings settings;
  settings.method = MethodFrom(solver.method);
  settings.coarse_operator = CoarseOperatorFrom(solver.coarse_operator);
  settings.levels = solver.levels;
  settings.tolerance = solver.tolerance;
  settings.max_iterations = solver.max_iterations;
  settings.substeps = solver.substeps;
  settings.strain_limit = solver.strain_limit;
  return settings;
}

costume_lcm::material_parameters ToMessage(const sim::Material& material) {
  costume_lcm::material_parameters p{};
  p.name = material.name;
  p.density = material.density;
  p.stretch_stiffness = material.stretch_stiffness;
  p.shear_stiffness = material.shear_stiffness;
  p.bending_rigidity = material.bending_rigidity;
  p.damping = material.damping;
  p.air_drag = material.air_drag;
  p.friction = material.friction;
  p.structural_spring_k = material.structural_spring_k;
  p.shear_spring_k = material.shear_spring_k;
  p.bending_spring_k = material.bending_spring_k;
  return p;
}

sim::Material FromMessage(const costume_lcm::material_parameters& p) {
  sim::Material material;
  material.name = p.name;
  material.density = p.density;
  material.stretch_stiffness = p.stretch_stiffness;
  material.shear_stiffness = p.shear_stiffness;
  material.bending_rigidity = p.bending_rigidity;
  material.damping = p.damping;
  material.air_drag = p.air_drag;
  material.friction = p.friction;
  material.structural_spring_k = p.structural_spring_k;
  material.shear_spring_k = p.shear_spring_k;
  material.bending_spring_k = p.bending_spring_k;
  return material;
}

costume_lcm::collision_parameters ToMessage(const sim::CollisionSettings& settings) {
  costume_lcm::collision_parameters p{};
  p.method = settings.method == sim::BodyCollisionMethod::kMesh ? CP::METHOD_MESH
                                                                : CP::METHOD_SUPERQUADRIC;
  p.thickness = settings.thickness;
  p.friction = settings.friction;
  p.max_skin_travel = settings.max_skin_travel;
  p.max_steps_per_frame = settings.max_steps_per_frame;
  p.superquadric_map_mb = settings.superquadric_map_mb;
  p.self_collision = settings.self_collision;
  return p;
}

sim::CollisionSettings FromMessage(const costume_lcm::collision_parameters& collision) {
  sim::CollisionSettings settings;
  settings.method = CollisionMethodFrom(collision.method);
  settings.thickness = collision.thickness;
  settings.friction = collision.friction;
  settings.max_skin_travel = collision.max_skin_travel;
  settings.max_steps_per_frame = collision.max_steps_per_frame;
  settings.superquadric_map_mb = collision.superquadric_map_mb;
  settings.self_collision = collision.self_collision;
  return settings;
}

}  // namespace costume::bus
