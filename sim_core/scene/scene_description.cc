#include "sim_core/scene/scene_description.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "sim_core/common/input_error.h"
#include "sim_core/common/thread_pool.h"

// The checks here need no file, so messages start with scene.source (and the garment's or
// sphere's line when it came from a file). The scene file parser (assets/scene_file.cc)
// makes the same checks with line and column; keep the ranges of both and of
// docs/scene_format.md in step.

namespace costume::sim {
namespace {

/// Panel axes must be unit length and orthogonal to within this.
constexpr double kAxisTolerance = 1e-6;
constexpr int kMinLatticeSize = 2;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr int kMaxLatticeSize = 1025;

/// Describes an interval as messages state it: "> 0", ">= 0", "(0, 1)", "[1, 1000]".
std::string DescribeRange(double lo, double hi, bool lo_open, bool hi_open) {
  if (std::isinf(hi)) return std::string(lo_open ? "> " : ">= ") + FormatValue(lo);
  return std::string(lo_open ? "(" : "[") + FormatValue(lo) + ", " + FormatValue(hi) +
         (hi_open ? ")" : "]");
}

std::string FormatVector(const Eigen::Vector3d& value) {
  return FormatValues({value.x(), value.y(), value.z()}, "[", "]");
}

std::string Quote(const std::string& text) { return "\"" + text + "\""; }

/// Throws the messages of ValidateScene, prefixed with where the scene came from:
/// "scenes/hang.toml: " or, for a part whose line is known, "scenes/hang.toml:14: ".
class Refuser {
 public:
  explicit Refuser(std::string source, int line = 0) : source_(std::move(source)), line_(line) {}

  /// The same source, pointing at `line` (0: unknown).
  Refuser AtLine(int line) const { return Refuser(source_, line); }

  std::string where() const { return line_ > 0 ? source_ + ":" + std::to_string(line_) : source_; }

  /// Throws "<where>: <field> = <value>: <problem>".
  [[noreturn]] void Refuse(const std::string& field, const std::string& value,
                           const std::string& problem) const {
    throw InputError(where() + ": " + field + " = " + value + ": " + problem);
  }

  /// Refuses `value` unless it is finite and inside the interval (nan and inf never are).
  void RequireNumber(const std::string& field, double value, double lo, double hi, bool lo_open,
                     bool hi_open, const std::string& unit) const {
    const bool inside =
        (lo_open ? value > lo : value >= lo) && (hi_open ? value < hi : value <= hi);
    if (std::isfinite(value) && inside) return;
    Refuse(field, FormatValue(value) + (unit.empty() ? "" : " " + unit),
           "allowed range " + DescribeRange(lo, hi, lo_open, hi_open));
  }

  void RequirePositive(const std::string& field, double value, const std::string& unit) const {
    RequireNumber(field, value, 0.0, kInfinity, true, true, unit);
  }

  void RequireNonNegative(const std::string& field, double value, const std::string& unit) const {
    RequireNumber(field, value, 0.0, kInfinity, false, true, unit);
  }

  void RequireInteger(const std::string& field, int value, int lo, int hi) const {
    if (value >= lo && value <= hi) return;
    Refuse(field, std::to_string(value),
           "allowed range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }

  void RequireFinite(const std::string& field, const Eigen::Vector3d& value,
                     const std::string& unit) const {
    if (value.allFinite()) return;
    Refuse(field, FormatVector(value) + " " + unit, "must be finite");
  }

  /// Refuses `value` unless each coordinate is finite and within ±`bound`.
  void RequireWithin(const std::string& field, const Eigen::Vector3d& value, double bound,
                     const std::string& unit) const {
    RequireFinite(field, value, unit);
    if (value.lpNorm<Eigen::Infinity>() <= bound) return;
    Refuse(field, FormatVector(value) + " " + unit,
           "allowed: each coordinate within ±" + FormatValue(bound));
  }

 private:
  std::string source_;
  int line_;
};

void ValidateSolver(const SolverSettings& solver, const Refuser& refuser) {
  refuser.RequireNumber("solver.tolerance", solver.tolerance, kMinSolverTolerance, 1.0, false, true, "");
  refuser.RequireInteger("solver.max_iterations", solver.max_iterations, 1, 100000);
  refuser.RequireInteger("solver.levels", solver.levels, 0, 16);
  refuser.RequireInteger("solver.threads", solver.threads, 0, ThreadPool::kMaxThreads);
  refuser.RequireInteger("solver.substeps", solver.substeps, 1, kMaxSubsteps);
  refuser.RequireNumber("solver.strain_limit", solver.strain_limit, 0.0, 10.0, false, false, "");
}

void ValidateMaterials(const std::vector<Material>& materials, const Refuser& refuser) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < materials.size(); ++i) {
    const std::string field = "material[" + std::to_string(i) + "]";
    if (materials[i].name.empty()) refuser.Refuse(field + ".name", "\"\"", "must not be empty");
    if (!names.insert(materials[i].name).second) {
      refuser.Refuse(field + ".name", Quote(materials[i].name), "duplicate material name");
    }
    ValidateMaterial(materials[i], refuser.where() + ": " + field);
  }
}

void ValidateAxis(const std::string& field, const Eigen::Vector3d& axis, const Refuser& refuser) {
  if (axis.allFinite() && std::abs(axis.norm() - 1.0) <= kAxisTolerance) return;
  refuser.Refuse(field, FormatVector(axis),
                 "must be a unit vector (length 1 within " + FormatValue(kAxisTolerance) + ")");
}

void ValidatePanel(const LatticePanel& panel, const std::string& field, const Refuser& refuser) {
  refuser.RequireFinite(field + ".origin", panel.origin, "m");
  ValidateAxis(field + ".u_axis", panel.u_axis, refuser);
  ValidateAxis(field + ".v_axis", panel.v_axis, refuser);
  const double dot = std::abs(panel.u_axis.dot(panel.v_axis));
  if (dot > kAxisTolerance) {
    refuser.Refuse(field + ".v_axis", FormatVector(panel.v_axis),
                   "must be orthogonal to u_axis = " + FormatVector(panel.u_axis) + " (|u·v| = " +
                       FormatValue(dot) + ", allowed <= " + FormatValue(kAxisTolerance) + ")");
  }
  refuser.RequirePositive(field + ".width", panel.width, "m");
  refuser.RequirePositive(field + ".height", panel.height, "m");
  refuser.RequireInteger(field + ".cols", panel.cols, kMinLatticeSize, kMaxLatticeSize);
  refuser.RequireInteger(field + ".rows", panel.rows, kMinLatticeSize, kMaxLatticeSize);
}

/// Scene materials first, then the built-in ones, as GarmentSpec::material is looked up.
bool IsKnownMaterial(const std::string& name, const std::vector<Material>& materials) {
  const std::vector<std::string> named = NamedMaterialNames();
  if (std::find(named.begin(), named.end(), name) != named.end()) return true;
  return std::any_of(materials.begin(), materials.end(),
                     [&](const Material& material) { return material.name == name; });
}

std::string KnownMaterialList(const std::vector<Material>& materials) {
  std::string list;
  for (const Material& material : materials) list += material.name + ", ";
  const std::vector<std::string> named = NamedMaterialNames();
  for (std::size_t i = 0; i < named.size(); ++i) list += (i ? ", " : "") + named[i];
  return list;
}

void ValidateGarment(const GarmentSpec& garment, std::size_t index,
                     const std::vector<Material>& materials, const Refuser& scene_refuser) {
  const Refuser refuser = scene_refuser.AtLine(garment.source_line);
  const std::string field = "garment[" + std::to_string(index) + "]";
  if (garment.name.empty()) refuser.Refuse(field + ".name", "\"\"", "must not be empty");
  const int shapes = garment.panel.has_value() + garment.mesh.has_value() +
                     garment.pattern.has_value() + (garment.model != nullptr);
  if (shapes != 1) {
    refuser.Refuse(field, Quote(garment.name),
                   std::string("has ") + (shapes ? "more than one of" : "none of") +
                       " a panel, a mesh, a pattern and a prebuilt model: a garment needs "
                       "exactly one of them");
  }
  if (garment.pattern) {
    refuser.RequireInteger(field + ".resolution", garment.pattern_resolution, 8, 1024);
  }
  if (!IsKnownMaterial(garment.material, materials)) {
    refuser.Refuse(field + ".material", Quote(garment.material),
                   "unknown material; the known materials are " + KnownMaterialList(materials));
  }
  for (std::size_t i = 0; i < garment.pin_points.size(); ++i) {
    refuser.RequireFinite(field + ".pin_points[" + std::to_string(i) + "]", garment.pin_points[i],
                          "m");
  }
  refuser.RequirePositive(field + ".pin_tolerance", garment.pin_tolerance, "m");
  if (garment.panel) ValidatePanel(*garment.panel, field + ".panel", refuser);
  if (garment.fit_outside_body && !garment.mesh) {
    refuser.Refuse(field + ".fit_outside_body", "true", "only mesh garments are fitted out of the body");
  }
}

void ValidateGarments(const SceneDescription& scene, const Refuser& refuser) {
  if (scene.garments.empty()) {
    refuser.Refuse("garment", "[]", "a scene needs at least one garment");
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < scene.garments.size(); ++i) {
    ValidateGarment(scene.garments[i], i, scene.materials, refuser);
    if (!names.insert(scene.garments[i].name).second) {
      refuser.AtLine(scene.garments[i].source_line)
          .Refuse("garment[" + std::to_string(i) + "].name", Quote(scene.garments[i].name),
                  "duplicate garment name");
    }
  }
}

void ValidateSphere(const SphereObstacleSpec& sphere, std::size_t index,
                    const Refuser& scene_refuser) {
  const Refuser refuser = scene_refuser.AtLine(sphere.source_line);
  const std::string field = "sphere[" + std::to_string(index) + "]";
  refuser.RequireWithin(field + ".center", sphere.center, kMaxCoordinate, "m");
  refuser.RequireNumber(field + ".radius", sphere.radius, 0.0, kMaxCoordinate, true, false, "m");
  refuser.RequireNumber(field + ".thickness", sphere.thickness, 0.0, kMaxThickness, false, false,
                        "m");
  refuser.RequireNumber(field + ".friction", sphere.friction, 0.0, kMaxFriction, false, false, "");
}

void ValidateAvatar(const SceneDescription& scene, const Refuser& scene_refuser) {
  if (!scene.avatar) {
    for (std::size_t i = 0; i < scene.garments.size(); ++i) {
      const GarmentSpec& garment = scene.garments[i];
      const Refuser refuser = scene_refuser.AtLine(garment.source_line);
      const std::string field = "garment[" + std::to_string(i) + "]";
      if (garment.pattern) {
        refuser.Refuse(field + ".pattern", Quote(*garment.pattern),
                       "a pattern garment is fitted to an avatar, and the scene has none");
      }
      if (garment.attach_to) {
        refuser.Refuse(field + ".attach_to", Quote(std::string(HAnimName(*garment.attach_to))),
                       "garments attach to an avatar, and the scene has none");
      }
      if (garment.fit_outside_body) {
        refuser.Refuse(field + ".fit_outside_body", "true",
                       "a garment is fitted out of an avatar, and the scene has none");
      }
    }
    return;
  }
  const AvatarSpec& avatar = *scene.avatar;
  const Refuser refuser = scene_refuser.AtLine(avatar.source_line);
  if (!avatar.avatar) refuser.Refuse("avatar", "none", "the avatar was not loaded");
  for (std::size_t i = 0; i < scene.garments.size(); ++i) {
    const GarmentSpec& garment = scene.garments[i];
    if (garment.made_for && !SameRestSkin(*avatar.avatar, *garment.made_for)) {
      scene_refuser.AtLine(garment.source_line)
          .Refuse("garment[" + std::to_string(i) + "]", Quote(garment.name),
                  "is modelled on the body '" + garment.made_for->name() +
                      "' and fits no other avatar; the avatar '" + avatar.avatar->name() +
                      "' has another skin: choose an avatar imported from that body");
    }
  }
  refuser.RequireNumber("avatar.thickness", avatar.thickness, 0.0, kMaxThickness, false, false,
                        "m");
  refuser.RequireNumber("avatar.friction", avatar.friction, 0.0, kMaxFriction, false, false, "");
  refuser.RequireWithin("avatar.position", avatar.motion.posture.root_translation,
                        kMaxCoordinate, "m");
  refuser.RequireNumber("avatar.superquadric_map_mb", avatar.superquadric_map_mb, 0.0,
                        kMaxSuperquadricMapMb, false, false, "MB");
  refuser.RequireNumber("avatar.max_skin_travel", avatar.max_skin_travel, 0.0, 1.0, false, false,
                        "m");
  refuser.RequireInteger("avatar.max_steps_per_frame", avatar.max_steps_per_frame, 1,
                         kMaxStepsPerFrame);
  refuser.RequireNumber("avatar.fit_time", avatar.motion.fit_time, 0.0, 60.0, false, false, "s");
  refuser.RequireNumber("avatar.blend_time", avatar.motion.blend_time, 0.0, 60.0, false, false, "s");
  refuser.RequireNumber("avatar.arm_spread (left)", avatar.motion.arm_spread[0], 0.0,
                        kMaxArmSpread, false, false, "rad");
  refuser.RequireNumber("avatar.arm_spread (right)", avatar.motion.arm_spread[1], 0.0,
                        kMaxArmSpread, false, false, "rad");
}

}  // namespace

const char* BodyCollisionMethodName(BodyCollisionMethod method) {
  return method == BodyCollisionMethod::kMesh ? "mesh" : "superquadric";
}

void ValidateScene(const SceneDescription& scene) {
  const Refuser refuser(scene.source);
  refuser.RequireNumber("duration", scene.duration, 0.0, 3600.0, true, false, "s");
  refuser.RequireNumber("frame_rate", scene.frame_rate, 1.0, 1000.0, false, false, "Hz");
  // Simulation::num_frames rounds: shorter than half a frame, a run simulates nothing and
  // reports timings of no frame.
  const double shortest = 0.5 / scene.frame_rate;
  if (scene.duration < shortest) {
    refuser.Refuse("duration", FormatValue(scene.duration) + " s",
                   "less than half a frame at " + FormatValue(scene.frame_rate) +
                       " Hz, so no frame would be simulated (allowed: at least " +
                       FormatValue(shortest) + " s)");
  }
  refuser.RequireWithin("gravity", scene.gravity, kMaxGravity, "m/s²");
  ValidateSolver(scene.solver, refuser);
  ValidateMaterials(scene.materials, refuser);
  ValidateGarments(scene, refuser);
  ValidateAvatar(scene, refuser);
  for (std::size_t i = 0; i < scene.spheres.size(); ++i) {
    ValidateSphere(scene.spheres[i], i, refuser);
  }
}

CollisionSettings CollisionSettingsOf(const SceneDescription& scene) {
  const AvatarSpec avatar = scene.avatar ? *scene.avatar : AvatarSpec{};
  CollisionSettings settings;
  settings.method = avatar.collision;
  settings.superquadric_map_mb = avatar.superquadric_map_mb;
  settings.thickness = avatar.thickness;
  settings.friction = avatar.friction;
  settings.max_skin_travel = avatar.max_skin_travel;
  settings.max_steps_per_frame = avatar.max_steps_per_frame;
  settings.self_collision = scene.effects.self_collision;
  return settings;
}

void ApplyCollisionSettings(const CollisionSettings& settings, SceneDescription& scene) {
  scene.effects.self_collision = settings.self_collision;
  if (!scene.avatar) return;
  AvatarSpec& avatar = *scene.avatar;
  avatar.collision = settings.method;
  avatar.superquadric_map_mb = settings.superquadric_map_mb;
  avatar.thickness = settings.thickness;
  avatar.friction = settings.friction;
  avatar.max_skin_travel = settings.max_skin_travel;
  avatar.max_steps_per_frame = settings.max_steps_per_frame;
}

}  // namespace costume::sim
