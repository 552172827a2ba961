#pragma once
/// @file
/// The solver, material and collision settings as they travel in a command
/// (KIND_SET_SOLVER, KIND_SET_MATERIAL, KIND_SET_COLLISION): one pair of conversions each,
/// used by the GUI that sends them and the simulation server that applies them, so the two
/// cannot drift apart.

#include "lcm_types/costume_lcm/collision_parameters.hpp"
#include "lcm_types/costume_lcm/material_parameters.hpp"
#include "lcm_types/costume_lcm/solver_parameters.hpp"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/scene_description.h"

namespace costume::bus {

costume_lcm::solver_parameters ToMessage(const sim::SolverSettings& settings);

/// Throws sim::InputError naming the field for an unknown method or coarse operator; the
/// numbers' ranges are checked where the scene is built (Simulation::Build).
sim::SolverSettings FromMessage(const costume_lcm::solver_parameters& solver);

costume_lcm::material_parameters ToMessage(const sim::Material& material);

/// The material's physical fields; its name is the sender's (the server names the fabric).
sim::Material FromMessage(const costume_lcm::material_parameters& material);

costume_lcm::collision_parameters ToMessage(const sim::CollisionSettings& settings);

/// Throws sim::InputError naming the field for an unknown method; the numbers' ranges are
/// checked where the settings are applied (Simulation::SetCollision, ValidateScene).
sim::CollisionSettings FromMessage(const costume_lcm::collision_parameters& collision);

}  // namespace costume::bus
