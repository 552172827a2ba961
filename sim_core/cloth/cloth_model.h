#pragma once
/// @file
/// The immutable mass-spring cloth model (paper §3.1, Figure 2a; DESIGN.md).
/// Model (what the garment is) is kept apart from state (where it is now, cloth_state.h), as
/// in MuJoCo's mjModel/mjData: a step is a function of both, and an edit that changes rest
/// lengths makes a new model revision instead of mutating a shared one.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace costume::sim {

/// n×3 points, one row per particle, stored row-major so that the x, y, z of each particle
/// are adjacent and the whole block maps onto a 3n vector (the solver's layout).
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Which role a spring plays. Structural springs join lattice neighbours (mesh edges),
/// shear springs join diagonals, bending springs skip one particle.
enum class SpringKind : std::uint8_t { kStructural = 0, kShear = 1, kBending = 2 };

/// "structural", "shear" or "bending".
const char* SpringKindName(SpringKind kind);

/// A linear spring with damping along its axis between particles a and b (a != b).
struct Spring {
  int a = 0;
  int b = 0;
  SpringKind kind = SpringKind::kStructural;
  /// Stiffness [N/m] >= 0.
  double stiffness = 0.0;
  /// Damping along the spring [N·s/m] >= 0.
  double damping = 0.0;
  /// Rest length [m] > 0.
  double rest_length = 0.0;
};

/// Plain data from which a ClothModel is made; every field is checked by ClothModel::Create.
struct ClothModelData {
  /// Human-readable name used in error messages ("garment 'skirt'").
  std::string name = "cloth";
  /// Rest positions (n×3) [m]; also the initial positions of a simulation.
  Points rest_positions;
  /// Particle masses (n) [kg] > 0.
  Eigen::VectorXd masses;
  /// Area each particle stands for (n) [m²] >= 0.
  Eigen::VectorXd areas;
  /// Linear air-drag coefficient of each particle (n) [N·s/m] >= 0: the material's air_drag
  /// times the particle's area. Left empty, it is taken as zero.
  Eigen::VectorXd drag;
  std::vector<Spring> springs;
  /// Indices of pinned particles (held at their positions).
  std::vector<int> pinned;
  /// Triangles for output and rendering (indices into the particles), counter-clockwise
  /// seen from the front side.
  std::vector<Eigen::Vector3i> triangles;
  /// For lattice panels: (rows, cols), particle (i, j) has index i·cols + j; (0, 0) otherwise.
  int lattice_rows = 0;
  int lattice_cols = 0;
};

/// An immutable, validated cloth model. Shared between the solver, the pyramid levels and
/// any number of states through std::shared_ptr<const ClothModel>.
class ClothModel {
 public:
  /// Validates `data` and makes the model. Throws InputError naming the model, the field,
  /// the offending value and the allowed range for: an empty particle set; non-finite
  /// positions; mass <= 0 or non-finite; negative or non-finite area; a spring with an
  /// index out of range, a == b, negative stiffness or damping, rest length <= 0 or
  /// non-finite, or the same pair twice; a pin index out of range or repeated; a triangle
  /// index out of range.
  static std::shared_ptr<const ClothModel> Create(ClothModelData data);

  int num_particles() const { return static_cast<int>(data_.masses.size()); }
  int num_springs() const { return static_cast<int>(data_.springs.size()); }
  const std::string& name() const { return data_.name; }
  const Points& rest_positions() const { return data_.rest_positions; }
  const Eigen::VectorXd& masses() const { return data_.masses; }
  const Eigen::VectorXd& areas() const { return data_.areas; }
  const Eigen::VectorXd& drag() const { return data_.drag; }
  const std::vector<Spring>& springs() const { return data_.springs; }
  const std::vector<int>& pinned() const { return data_.pinned; }
  /// True for pinned particles (n entries).
  const std::vector<bool>& is_pinned() const { return is_pinned_; }
  const std::vector<Eigen::Vector3i>& triangles() const { return data_.triangles; }
  int lattice_rows() const { return data_.lattice_rows; }
  int lattice_cols() const { return data_.lattice_cols; }
  double total_mass() const { return data_.masses.sum(); }
  const ClothModelData& data() const { return data_; }

  /// A new model revision whose spring rest lengths are `rest_lengths` (num_springs()
  /// entries, each finite and > 0); everything else is copied. Throws InputError.
  std::shared_ptr<const ClothModel> WithRestLengths(const Eigen::VectorXd& rest_lengths) const;

 private:
  explicit ClothModel(ClothModelData data);
  ClothModelData data_;
  std::vector<bool> is_pinned_;
};

}  // namespace costume::sim
