#pragma once
/// @file
/// The "edited-garment" format: a garment's prebuilt cloth model saved whole, so that a
/// garment whose rest lengths were edited (stretch-energy elimination, paper §5.3) keeps
/// them when stored in the catalogue and loaded again. Read back, it simulates exactly as
/// the model it was written from (every double is stored bit for bit).
///
/// Layout (little-endian), format version 1:
///   8 bytes   magic "CDGARMNT"
///   u32       format version (1)
///   u32       header length H; H bytes of JSON:
///             {"name", "attached_to" (H-Anim joint name or null), "material" {every
///              sim::Material field}, "num_particles", "num_springs", "num_pins",
///              "num_triangles", "lattice_rows", "lattice_cols", "has_drag"}
///   f64 × 3n  rest positions [m], particle by particle
///   f64 × n   masses [kg];  f64 × n areas [m²];  f64 × n drag [N·s/m] (when has_drag)
///   springs   per spring: i32 a, i32 b, u8 kind (0 structural, 1 shear, 2 bending),
///             f64 stiffness [N/m], f64 damping [N·s/m], f64 rest length [m]
///   i32 × p   pinned particle indices
///   i32 × 3t  triangles (counter-clockwise from the front)
/// Nothing may follow. A reader refuses another magic, a newer version, and sizes that do
/// not match; the model is then validated by sim::ClothModel::Create.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim_core/avatar/hanim.h"
#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/simulation.h"

namespace costume::assets {

/// A garment as a prebuilt model.
struct EditedGarment {
  std::shared_ptr<const sim::ClothModel> model;
  /// The joint its pinned particles are held by (none: pinned in space).
  std::optional<sim::HAnimJoint> attached_to;
  /// The fabric it was built from (kept for friction, drag and the catalogue's record; the
  /// springs already carry its stiffness).
  sim::Material material;
};

/// The format's version written by WriteEditedGarment.
inline constexpr std::uint32_t kEditedGarmentVersion = 1;

/// The bytes of `garment` (model must not be null).
std::vector<std::uint8_t> WriteEditedGarment(const EditedGarment& garment);

/// Reads bytes written by WriteEditedGarment. Throws sim::InputError naming `source` and
/// what is wrong (magic, version, a size, a field, or what ClothModel::Create refuses).
EditedGarment ReadEditedGarment(const std::vector<std::uint8_t>& bytes, const std::string& source);

/// The garment `name` of a running simulation as an edited garment: its particles, springs
/// (with the current rest lengths, edits included), pins and triangles taken out of the
/// merged model, the joint its pinned particles follow, and its material. Throws
/// sim::InputError for a name the simulation does not have.
EditedGarment EditedGarmentFromSimulation(const sim::Simulation& simulation,
                                          const std::string& name);

}  // namespace costume::assets
