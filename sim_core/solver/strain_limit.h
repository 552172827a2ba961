#pragma once
/// @file
/// Strain limiting after Provot 1995 ("Deformation constraints in a mass-spring model to
/// describe rigid cloth behavior", the paper's [Pro95]): structural and shear springs
/// stretched beyond (1 + limit)·rest are shortened back to that length by moving their ends,
/// and the ends stop separating along the spring (an inelastic contact, so kinetic energy
/// only drops; Provot's own velocity update, correction / h, was measured to add energy).
///
/// Why: one linearisation per step treats a spring swung through a large angle as if it
/// only translated, and comes out of such a step stretched (the drape at N = 129 reached
/// 200 % strain on impact, with either solver). Real cloth barely stretches past 10 %, so
/// capping it there removes the artefact without touching cloth that behaves.

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/cloth_state.h"

namespace costume::sim {

/// Shortens over-stretched structural and shear springs of `state` in at most `passes`
/// Gauss-Seidel sweeps (in spring order, so deterministic). Each correction is split between
/// the ends by inverse mass (pinned ends do not move), and so is the impulse that removes
/// the ends' separating velocity along the spring (momentum is kept). Returns the number of
/// corrections made. `limit` > 0 [-] (0.1 = 10 %). Never throws; never allocates.
int LimitStrain(const ClothModel& model, double limit, int passes, ClothState& state);

}  // namespace costume::sim
