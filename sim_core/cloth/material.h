#pragma once
/// @file
/// Fabric material in physical units, independent of how finely the cloth is sampled.
/// How these map onto spring constants is documented where the springs are built
/// (lattice_panel.h for panels, mesh_cloth.h for general meshes) and in docs/cloth_model.md.

#include <string>
#include <vector>

namespace costume::sim {

/// Largest values a fabric (a Material) may have. Each lies far beyond any fabric, so it refuses
/// only mistakes: a damaged scene file's density of 1e300 kg/m² ran with the cloth frozen, the
/// solver stopping at once every step, without a word of why. The stability tests' extremes
/// (tests/sim_core/scene/stability_matrix_test.cc) lie within these.
/// Mass per area [kg/m²]: heavy leather is about 1.5; the stability tests' heaviest sheet,
/// 1 kg particles 129 × 129 to the square metre, 1.7e4.
inline constexpr double kMaxDensity = 1e5;
/// Sheet stiffness and per-spring constants [N/m]: a 0.5 mm steel sheet's E·t is 1e8; the
/// stability tests go to 1e7.
inline constexpr double kMaxStiffness = 1e8;
/// Bending rigidity [N·m]: a 1 mm steel sheet's E·t³/12 is about 17.
inline constexpr double kMaxBendingRigidity = 100.0;
/// Spring damping time [s]: fabrics measure about 1e-3.
inline constexpr double kMaxDamping = 10.0;
/// Air drag [N·s/m per m²]: fabrics use about 0.02.
inline constexpr double kMaxAirDrag = 100.0;
/// Coulomb friction coefficient [-] of a fabric, the skin or a sphere: rubber on rubber is
/// about 1.2.
inline constexpr double kMaxFriction = 2.0;

/// A fabric, in SI units. Defaults are "stiff cotton" of docs/BENCHMARKS.md's scenes.
struct Material {
  std::string name = "stiff_cotton";
  /// Mass per area [kg/m²].
  double density = 0.1;
  /// Sheet stretch stiffness [N/m]: on a square lattice this is the structural spring
  /// constant whatever the spacing (a sheet of width w stretched by strain e pulls with
  /// stretch_stiffness·e·w newtons).
  double stretch_stiffness = 1000.0;
  /// Sheet shear stiffness [N/m]: the shear (diagonal) spring constant on a square lattice.
  double shear_stiffness = 1000.0;
  /// Bending rigidity [N·m]; a bending spring spanning 2h gets k = bending_rigidity / h².
  double bending_rigidity = 1e-5;
  /// Spring damping time [s]: each spring's damping coefficient is c = damping · k [N·s/m].
  double damping = 1e-3;
  /// Linear air drag [N·s/m per m² of cloth]: a particle of area a feels −air_drag·a·v.
  double air_drag = 0.02;
  /// Coulomb friction coefficient against obstacles [-]: a contact's coefficient is the
  /// geometric mean of this and the obstacle's (the avatar's or a sphere's friction;
  /// MixFriction, sim_core/collision/contact.h).
  double friction = 0.3;
  /// When > 0, the spring constants below override the sheet stiffnesses [N/m] for every
  /// spring of that kind (used for like-for-like runs against Blender's per-spring presets).
  double structural_spring_k = 0.0;
  double shear_spring_k = 0.0;
  double bending_spring_k = 0.0;
};

/// Checks every field against its range (0 or above, up to the kMax values above; density
/// above 0); throws InputError naming `context`.field, its value and range.
void ValidateMaterial(const Material& material, const std::string& context);

/// Built-in named materials: the fabric presets at their measured stiffness (cotton, silk,
/// wool, denim, leather: fabric_presets.h) and the benchmark materials "stiff_cotton" and
/// "blender_cotton" (blender_cotton needs the lattice size, see BlenderCotton). Throws
/// InputError for an unknown name, listing the known ones.
Material NamedMaterial(const std::string& name);

/// The names NamedMaterial knows: the presets, then stiff_cotton, blender_cotton.
std::vector<std::string> NamedMaterialNames();

/// Blender 3.4's Cotton preset converted to per-spring constants for an n×n lattice over
/// 1 m (docs/BENCHMARKS.md): about 147, 76, 38.5 N/m at n = 33, 65, 129.
Material BlenderCotton(int n);

}  // namespace costume::sim
