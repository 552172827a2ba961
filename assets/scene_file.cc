#include "assets/scene_file.h"

#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>

#include "assets/avatar_import.h"
#include "assets/clip_import.h"
#include "assets/import_units.h"
#include "assets/makehuman_import.h"
#include "assets/mesh_import.h"
#include "sim_core/avatar/pose.h"
#include "sim_core/common/thread_pool.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/scene/garment_fit.h"
#include "sim_core/common/input_error.h"

// How the parser works: every table is read through a TableView, which refuses unknown keys
// first (typo protection) and hands out Fields; a Field knows its qualified name
// ("garment[0].panel.size") and its position (the key's, or an array element's own), so every
// check can throw the `file:line:column: name = value unit: problem` message of scene_file.h.
// Ranges are checked here, where the line is known; ValidateScene repeats the file-independent
// checks afterwards as a safety net.

namespace costume::assets {
namespace {

using sim::FormatValue;
using sim::InputError;

constexpr double kInfinity = std::numeric_limits<double>::infinity();
/// Panel axes count as orthogonal when |u·v| of the normalised axes is at most this.
constexpr double kAxisOrthogonalityTolerance = 1e-6;
/// Longest value quoted in a message; longer ones (big arrays) are cut.
constexpr std::size_t kMaxQuotedValueLength = 80;

constexpr std::string_view kStiffCotton = "stiff_cotton";

// ---- built-in scenes --------------------------------------------------------------------

struct BuiltInScene {
  std::string_view name;
  std::string_view text;
};

/// Generated at build time from scenes/*.toml by cmake/embed_text.cmake.
constexpr BuiltInScene kBuiltInScenes[] = {
#include "generated/builtin_scenes.inc"
};

// ---- formatting -------------------------------------------------------------------------

std::string Join(const std::vector<std::string>& items) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : ", ") + item;
  return text;
}

std::string Quote(std::string_view text) { return "\"" + std::string(text) + "\""; }

/// A TOML value as a message quotes it: numbers in shortest form, strings quoted.
std::string DescribeValue(const toml::node& node) {
  std::string text;
  if (const auto* integer = node.as_integer()) {
    text = std::to_string(integer->get());
  } else if (const auto* number = node.as_floating_point()) {
    text = FormatValue(number->get());
  } else if (const auto* boolean = node.as_boolean()) {
    text = boolean->get() ? "true" : "false";
  } else if (const auto* string = node.as_string()) {
    text = Quote(string->get());
  } else if (const auto* array = node.as_array()) {
    std::vector<std::string> elements;
    for (const toml::node& element : *array) elements.push_back(DescribeValue(element));
    text = "[" + Join(elements) + "]";
  } else if (node.is_table()) {
    text = "{...}";
  } else {
    std::ostringstream out;  // dates and times: TOML's own spelling
    node.visit([&out](const auto& value) { out << value; });
    text = out.str();
  }
  if (text.size() > kMaxQuotedValueLength) text = text.substr(0, kMaxQuotedValueLength - 3) + "...";
  return text;
}

/// "a string", "an integer", ... for "expected X, found Y" messages.
std::string TypeName(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a float";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::array: return "an array";
    case toml::node_type::table: return "a table";
    default: return "a date or time";
  }
}

/// An allowed interval for a number, for the check and for the message stating it.
struct Range {
  double lo = -kInfinity;
  double hi = kInfinity;
  bool lo_open = true;
  bool hi_open = true;

  bool Contains(double value) const {
    return (lo_open ? value > lo : value >= lo) && (hi_open ? value < hi : value <= hi);
  }

  /// What a value must be, e.g. "must be a finite number > 0" or "... in (0, 1)".
  std::string Requirement() const {
    const std::string text = "must be a finite number";
    const bool has_lo = lo > -kInfinity;
    const bool has_hi = hi < kInfinity;
    if (has_lo && has_hi) {
      return text + " in " + (lo_open ? "(" : "[") + FormatValue(lo) + ", " + FormatValue(hi) +
             (hi_open ? ")" : "]");
    }
    if (has_lo) return text + (lo_open ? " > " : " >= ") + FormatValue(lo);
    if (has_hi) return text + (hi_open ? " < " : " <= ") + FormatValue(hi);
    return text;
  }
};

constexpr Range kAnyNumber{};
constexpr Range kPositive{0.0, kInfinity, true, true};
constexpr Range kNonNegative{0.0, kInfinity, false, true};
constexpr Range kDurationRange{0.0, 3600.0, true, false};
constexpr Range kCoordinateRange{-sim::kMaxCoordinate, sim::kMaxCoordinate, false, false};
constexpr Range kGravityRange{-sim::kMaxGravity, sim::kMaxGravity, false, false};
constexpr Range kThicknessRange{0.0, sim::kMaxThickness, false, false};
constexpr Range kFrictionRange{0.0, sim::kMaxFriction, false, false};
constexpr Range kStiffnessRange{0.0, sim::kMaxStiffness, false, false};
constexpr Range kFrameRateRange{1.0, 1000.0, false, false};
constexpr Range kToleranceRange{sim::kMinSolverTolerance, 1.0, false, true};
constexpr Range kStrainLimitRange{0.0, 10.0, false, false};
constexpr Range kPostureRange{-sim::kMaxPostureDegrees, sim::kMaxPostureDegrees, false, false};

// ---- fields and tables ------------------------------------------------------------------

/// The text being parsed: its name for messages and the folder mesh paths start from.
struct Source {
  std::string name;
  std::string base_dir;
  AvatarFiles avatar_files = AvatarFiles::kAllowed;
};

std::string At(const Source& source, toml::source_position position) {
  return source.name + ":" + std::to_string(position.line) + ":" + std::to_string(position.column);
}

/// A value of the file with its qualified name ("garment[0].panel.size") and the position
/// messages point at: its key's, or for an array element its own.
struct Field {
  const toml::node* node;
  std::string name;
  toml::source_position position;
  const Source* source;

  /// Throws `file:line:column: name = value unit: problem` (no value for tables).
  [[noreturn]] void Refuse(const std::string& problem, const std::string& unit = "") const {
    std::string text = At(*source, position) + ": " + name;
    if (!node->is_table()) text += " = " + DescribeValue(*node) + (unit.empty() ? "" : " " + unit);
    throw InputError(text + ": " + problem);
  }

  /// Element `index` of an array field.
  Field Element(std::size_t index) const {
    const toml::node& element = *node->as_array()->get(index);
    return Field{&element, name + "[" + std::to_string(index) + "]", element.source().begin,
                 source};
  }
};

/// A table of the file with the name its fields are qualified with ("garment[0].panel",
/// "" at the top level) and the header that introduces it ("[garment.panel]").
class TableView {
 public:
  TableView(const toml::table& table, std::string name, std::string header,
            toml::source_position position, const Source& source)
      : table_(&table),
        name_(std::move(name)),
        header_(std::move(header)),
        position_(position),
        source_(&source) {}

  const std::string& name() const { return name_; }
  const Source& source() const { return *source_; }
  int line() const { return static_cast<int>(position_.line); }

  /// Refuses the first key (in file order) that is not in `allowed`, listing the allowed.
  void RefuseUnknownKeys(std::initializer_list<std::string_view> allowed) const {
    RefuseUnknownKeys(std::vector<std::string_view>(allowed));
  }
  void RefuseUnknownKeys(const std::vector<std::string_view>& allowed) const {
    const toml::key* first_unknown = nullptr;
    for (auto&& [key, node] : *table_) {
      if (std::find(allowed.begin(), allowed.end(), key.str()) != allowed.end()) continue;
      if (!first_unknown || key.source().begin < first_unknown->source().begin) {
        first_unknown = &key;
      }
    }
    if (first_unknown) {
      Find(first_unknown->str())
          ->Refuse("unknown key; allowed keys for " + header_ + ": " +
                   Join(std::vector<std::string>(allowed.begin(), allowed.end())));
    }
  }

  /// The field `key`, or nullopt when the table has none.
  std::optional<Field> Find(std::string_view key) const {
    const auto found = table_->find(key);
    if (found == table_->end()) return std::nullopt;
    return Field{&found->second, FieldName(key), found->first.source().begin, source_};
  }

  /// The field `key`; when it is missing, throws pointing at the table.
  Field Require(std::string_view key) const {
    std::optional<Field> field = Find(key);
    if (!field) Refuse(FieldName(key) + ": missing; every " + header_ + " needs it");
    return *field;
  }

  /// Throws `file:line:column: problem` at the table's line.
  [[noreturn]] void Refuse(const std::string& problem) const {
    throw InputError(At(*source_, position_) + ": " + problem);
  }

 private:
  std::string FieldName(std::string_view key) const {
    return name_.empty() ? std::string(key) : name_ + "." + std::string(key);
  }

  const toml::table* table_;
  std::string name_;
  std::string header_;
  toml::source_position position_;
  const Source* source_;
};

// ---- values -----------------------------------------------------------------------------

/// A number (integers are accepted where floats are expected), finite and in `range`.
double ReadNumber(const Field& field, const Range& range, const std::string& unit) {
  double value = 0.0;
  if (const auto* integer = field.node->as_integer()) {
    value = static_cast<double>(integer->get());
  } else if (const auto* number = field.node->as_floating_point()) {
    value = number->get();
  } else {
    field.Refuse("expected a number, found " + TypeName(*field.node), unit);
  }
  if (!std::isfinite(value) || !range.Contains(value)) field.Refuse(range.Requirement(), unit);
  return value;
}

/// An integer in [lo, hi]; floats are refused, as 33.5 particles has no meaning.
int ReadInteger(const Field& field, int lo, int hi) {
  const auto* integer = field.node->as_integer();
  if (!integer) field.Refuse("expected an integer, found " + TypeName(*field.node));
  const std::int64_t value = integer->get();
  if (value < lo || value > hi) {
    field.Refuse("must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return static_cast<int>(value);
}

bool ReadBool(const Field& field) {
  const auto* boolean = field.node->as_boolean();
  if (!boolean) field.Refuse("expected true or false, found " + TypeName(*field.node));
  return boolean->get();
}

/// A non-empty string.
std::string ReadName(const Field& field) {
  const auto* string = field.node->as_string();
  if (!string) field.Refuse("expected a string, found " + TypeName(*field.node));
  if (string->get().empty()) field.Refuse("must not be empty");
  return string->get();
}

/// One of `choices`.
template <typename Choices>
std::string ReadChoice(const Field& field, const Choices& choices) {
  const auto* string = field.node->as_string();
  if (!string || std::find(choices.begin(), choices.end(), string->get()) == choices.end()) {
    std::vector<std::string> quoted;
    for (std::string_view choice : choices) quoted.push_back(Quote(choice));
    field.Refuse("must be one of " + Join(quoted));
  }
  return string->get();
}

std::string ReadChoice(const Field& field, std::initializer_list<std::string_view> choices) {
  return ReadChoice<std::initializer_list<std::string_view>>(field, choices);
}

/// An array of exactly `length` elements (any length when nullopt); `what` names the
/// expected shape for the message, e.g. "an array of 3 numbers [x, y, z]".
const toml::array& ReadArray(const Field& field, std::optional<std::size_t> length,
                             const std::string& what, const std::string& unit) {
  const auto* array = field.node->as_array();
  if (!array) field.Refuse("expected " + what + ", found " + TypeName(*field.node), unit);
  if (length && array->size() != *length) {
    field.Refuse("expected " + what + ", found " + std::to_string(array->size()) + " element" +
                     (array->size() == 1 ? "" : "s"),
                 unit);
  }
  return *array;
}

Eigen::Vector3d ReadVector3(const Field& field, const std::string& unit,
                            const Range& range = kAnyNumber) {
  ReadArray(field, 3, "an array of 3 numbers [x, y, z]", unit);
  Eigen::Vector3d vector;
  for (int i = 0; i < 3; ++i) vector[i] = ReadNumber(field.Element(i), range, unit);
  return vector;
}

/// A non-zero direction, normalised.
Eigen::Vector3d ReadDirection(const Field& field) {
  const Eigen::Vector3d direction = ReadVector3(field, "");
  const double length = direction.norm();
  if (!(length > 0.0) || !std::isfinite(length)) {
    field.Refuse("must be a non-zero direction (it is normalised)");
  }
  return direction / length;
}

/// A list of points [[x, y, z], ...] of any length.
std::vector<Eigen::Vector3d> ReadPoints(const Field& field, const std::string& unit) {
  const toml::array& array =
      ReadArray(field, std::nullopt, "an array of points [[x, y, z], ...]", unit);
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < array.size(); ++i)
    points.push_back(ReadVector3(field.Element(i), unit, kCoordinateRange));
  return points;
}

double NumberOr(const TableView& table, std::string_view key, double fallback, const Range& range,
                const std::string& unit) {
  const std::optional<Field> field = table.Find(key);
  return field ? ReadNumber(*field, range, unit) : fallback;
}

int IntegerOr(const TableView& table, std::string_view key, int fallback, int lo, int hi) {
  const std::optional<Field> field = table.Find(key);
  return field ? ReadInteger(*field, lo, hi) : fallback;
}

bool BoolOr(const TableView& table, std::string_view key, bool fallback) {
  const std::optional<Field> field = table.Find(key);
  return field ? ReadBool(*field) : fallback;
}

Eigen::Vector3d Vector3Or(const TableView& table, std::string_view key,
                          const Eigen::Vector3d& fallback, const std::string& unit,
                          const Range& range) {
  const std::optional<Field> field = table.Find(key);
  return field ? ReadVector3(*field, unit, range) : fallback;
}

/// The sub-table `key` (a [header] or an inline table), or nullopt when absent.
std::optional<TableView> FindTable(const TableView& parent, std::string_view key,
                                   const std::string& header) {
  const std::optional<Field> field = parent.Find(key);
  if (!field) return std::nullopt;
  const auto* table = field->node->as_table();
  if (!table) {
    field->Refuse("expected a table, written " + header + ", found " + TypeName(*field->node));
  }
  return TableView(*table, field->name, header, table->source().begin, parent.source());
}

/// The tables of array `key` ([[header]] tables), empty when absent.
std::vector<TableView> FindTableArray(const TableView& parent, std::string_view key,
                                      const std::string& header) {
  std::vector<TableView> tables;
  const std::optional<Field> field = parent.Find(key);
  if (!field) return tables;
  if (!field->node->is_array()) {
    field->Refuse("expected an array of tables, written " + header + " (double brackets), found " +
                  TypeName(*field->node));
  }
  for (std::size_t i = 0; i < field->node->as_array()->size(); ++i) {
    const Field element = field->Element(i);
    const auto* table = element.node->as_table();
    if (!table)
      element.Refuse("expected a table, written " + header + ", found " + TypeName(*element.node));
    tables.emplace_back(*table, element.name, header, element.position, parent.source());
  }
  return tables;
}

/// Refuses a name used before by another table of the same kind, pointing at both.
void RefuseDuplicateName(std::map<std::string, toml::source_position>& seen, const Field& field,
                         const std::string& name, const std::string& kind) {
  const auto [previous, inserted] = seen.emplace(name, field.position);
  if (!inserted) {
    field.Refuse("duplicate " + kind + " name; the first is at line " +
                 std::to_string(previous->second.line));
  }
}

// ---- tables -----------------------------------------------------------------------------

sim::SolverSettings ParseSolver(const TableView& table) {
  table.RefuseUnknownKeys(
      {"method", "tolerance", "max_iterations", "levels", "coarse_operator", "substeps",
       "strain_limit", "threads"});
  sim::SolverSettings solver;
  if (const std::optional<Field> method = table.Find("method")) {
    const std::string name =
        ReadChoice(*method, {"pcg", "hierarchical", "multigrid", "direct"});
    solver.method = name == "pcg"            ? sim::SolverMethod::kPcg
                    : name == "hierarchical" ? sim::SolverMethod::kHierarchical
                    : name == "multigrid"    ? sim::SolverMethod::kMultigrid
                                             : sim::SolverMethod::kDirect;
  }
  solver.tolerance = NumberOr(table, "tolerance", solver.tolerance, kToleranceRange, "");
  solver.max_iterations = IntegerOr(table, "max_iterations", solver.max_iterations, 1, 100000);
  solver.levels = IntegerOr(table, "levels", solver.levels, 0, 16);
  if (const std::optional<Field> coarse = table.Find("coarse_operator")) {
    solver.coarse_operator = ReadChoice(*coarse, {"galerkin", "rediscretised"}) == "galerkin"
                                 ? sim::CoarseOperator::kGalerkin
                                 : sim::CoarseOperator::kRediscretised;
  }
  solver.substeps = IntegerOr(table, "substeps", solver.substeps, 1, sim::kMaxSubsteps);
  solver.strain_limit =
      NumberOr(table, "strain_limit", solver.strain_limit, kStrainLimitRange, "");
  solver.threads = IntegerOr(table, "threads", solver.threads, 0, sim::ThreadPool::kMaxThreads);
  return solver;
}

sim::Effects ParseEffects(const TableView& table) {
  table.RefuseUnknownKeys({"air_drag", "friction", "self_collision"});
  sim::Effects effects;
  effects.air_drag = BoolOr(table, "air_drag", effects.air_drag);
  effects.friction = BoolOr(table, "friction", effects.friction);
  effects.self_collision = BoolOr(table, "self_collision", effects.self_collision);
  return effects;
}

/// The built-in material a [[material]] starts from: `base` (a fabric preset, stiff_cotton
/// or blender_cotton: sim::NamedMaterialNames), stiff_cotton by default.
sim::Material BaseMaterial(const TableView& table) {
  const std::optional<Field> base = table.Find("base");
  return sim::NamedMaterial(base ? ReadChoice(*base, sim::NamedMaterialNames())
                                 : std::string(kStiffCotton));
}

sim::Material ParseMaterial(const TableView& table) {
  table.RefuseUnknownKeys({"name", "base", "density", "stretch_stiffness", "shear_stiffness",
                           "bending_rigidity", "damping", "air_drag", "friction",
                           "structural_spring_k", "shear_spring_k", "bending_spring_k"});
  sim::Material m = BaseMaterial(table);
  m.name = ReadName(table.Require("name"));
  m.density = NumberOr(table, "density", m.density, {0.0, sim::kMaxDensity, true, false}, "kg/m²");
  m.stretch_stiffness =
      NumberOr(table, "stretch_stiffness", m.stretch_stiffness, kStiffnessRange, "N/m");
  m.shear_stiffness = NumberOr(table, "shear_stiffness", m.shear_stiffness, kStiffnessRange, "N/m");
  m.bending_rigidity = NumberOr(table, "bending_rigidity", m.bending_rigidity,
                                {0.0, sim::kMaxBendingRigidity, false, false}, "N·m");
  m.damping = NumberOr(table, "damping", m.damping, {0.0, sim::kMaxDamping, false, false}, "s");
  m.air_drag = NumberOr(table, "air_drag", m.air_drag, {0.0, sim::kMaxAirDrag, false, false},
                        "N·s/m per m²");
  m.friction = NumberOr(table, "friction", m.friction, kFrictionRange, "");
  m.structural_spring_k =
      NumberOr(table, "structural_spring_k", m.structural_spring_k, kStiffnessRange, "N/m");
  m.shear_spring_k = NumberOr(table, "shear_spring_k", m.shear_spring_k, kStiffnessRange, "N/m");
  m.bending_spring_k =
      NumberOr(table, "bending_spring_k", m.bending_spring_k, kStiffnessRange, "N/m");
  return m;
}

std::vector<sim::Material> ParseMaterials(const TableView& root) {
  std::vector<sim::Material> materials;
  std::map<std::string, toml::source_position> seen;
  for (const TableView& table : FindTableArray(root, "material", "[[material]]")) {
    materials.push_back(ParseMaterial(table));
    RefuseDuplicateName(seen, table.Require("name"), materials.back().name, "material");
  }
  return materials;
}

/// Names a garment may use: the scene's materials, then the built-in ones.
std::vector<std::string> KnownMaterialNames(const std::vector<sim::Material>& materials) {
  std::vector<std::string> names;
  for (const sim::Material& material : materials) names.push_back(material.name);
  for (const std::string& built_in : sim::NamedMaterialNames()) {
    if (std::find(names.begin(), names.end(), built_in) == names.end()) {
      names.push_back(built_in);
    }
  }
  return names;
}

/// Refuses panel axes that are not orthogonal, pointing at v_axis (or u_axis if only it
/// is given: the default axes are orthogonal, so one of them was written).
void RefuseSkewAxes(const TableView& table, const sim::LatticePanel& panel) {
  const double dot = std::abs(panel.u_axis.dot(panel.v_axis));
  if (dot <= kAxisOrthogonalityTolerance) return;
  std::optional<Field> culprit = table.Find("v_axis");
  if (!culprit) culprit = table.Find("u_axis");
  culprit->Refuse("u_axis and v_axis must be orthogonal: |u·v| = " + FormatValue(dot) +
                  " after normalising, allowed <= " + FormatValue(kAxisOrthogonalityTolerance));
}

sim::LatticePanel ParsePanel(const TableView& table) {
  table.RefuseUnknownKeys({"origin", "u_axis", "v_axis", "size", "resolution"});
  sim::LatticePanel panel;
  panel.origin = Vector3Or(table, "origin", panel.origin, "m", kCoordinateRange);
  if (const std::optional<Field> u_axis = table.Find("u_axis"))
    panel.u_axis = ReadDirection(*u_axis);
  if (const std::optional<Field> v_axis = table.Find("v_axis"))
    panel.v_axis = ReadDirection(*v_axis);
  RefuseSkewAxes(table, panel);
  if (const std::optional<Field> size = table.Find("size")) {
    ReadArray(*size, 2, "an array of 2 numbers [width, height]", "m");
    panel.width = ReadNumber(size->Element(0), kPositive, "m");
    panel.height = ReadNumber(size->Element(1), kPositive, "m");
  }
  if (const std::optional<Field> resolution = table.Find("resolution")) {
    ReadArray(*resolution, 2, "an array of 2 integers [cols, rows]", "");
    panel.cols = ReadInteger(resolution->Element(0), 2, 1025);
    panel.rows = ReadInteger(resolution->Element(1), 2, 1025);
  }
  return panel;
}

/// `file` as given when absolute, else relative to the scene file's folder.
std::string ResolvePath(const std::string& base_dir, const std::string& file) {
  std::filesystem::path path(file);
  if (path.is_relative() && !base_dir.empty()) path = std::filesystem::path(base_dir) / path;
  return path.lexically_normal().string();
}

/// Runs an importer on a file the field names; its refusal (which names the file) is
/// placed at the field.
template <typename Load>
auto ImportAt(const Field& field, const std::string& path, Load&& load) {
  try {
    return load();
  } catch (const InputError& error) {
    const std::string problem = error.what();
    field.Refuse(problem.find(path) != std::string::npos ? problem : path + ": " + problem);
  }
}

bool IsMakeHumanGarment(const std::string& path) { return LowerExtension(path) == ".mhclo"; }

/// [garment.mesh]: a mesh file through assimp, or a MakeHuman garment (.mhclo) fitted to the
/// MakeHuman body `makehuman_body` (its base.obj; empty when the avatar is not MakeHuman's).
sim::SurfaceMesh ParseMesh(const TableView& table, const std::string& makehuman_body) {
  table.RefuseUnknownKeys({"file", "scale", "offset", "weld_below", "fit_outside_body"});
  const Field file = table.Require("file");
  const std::string path = ResolvePath(table.source().base_dir, ReadName(file));
  const bool makehuman = IsMakeHumanGarment(path);
  MeshImportOptions options;
  options.scale = NumberOr(table, "scale", makehuman ? 0.1 : options.scale, kPositive,
                           "m per file unit");
  options.offset = Vector3Or(table, "offset", options.offset, "m", kCoordinateRange);
  const double weld = NumberOr(table, "weld_below", 0.0, {0.0, 0.1, false, false}, "m");
  if (makehuman && makehuman_body.empty()) {
    file.Refuse("a MakeHuman garment is fitted to MakeHuman's body: [avatar] needs model = "
                "its base.obj, with skeleton and weights");
  }
  return ImportAt(file, path, [&] {
    if (!makehuman) return sim::WeldShortEdges(ImportSurfaceMesh(path, options), weld);
    // MakeHuman's own fit: each vertex from three body vertices plus an offset (the .mhclo).
    sim::SurfaceMesh fitted = LoadMakeHumanGarment(path, ReadObj(makehuman_body), options.scale);
    fitted.vertices.rowwise() += options.offset.transpose();
    return sim::WeldShortEdges(fitted, weld);
  });
}

/// What a garment can be fitted and held to: the scene's avatar, and MakeHuman's base.obj
/// when that avatar is MakeHuman's (for .mhclo garments).
struct GarmentContext {
  std::vector<std::string> materials;
  const sim::AvatarSpec* avatar = nullptr;
  std::string makehuman_body;
};

/// `pin_waistband = band`: the mesh's open boundary loops within `band` of the avatar's
/// waist (its vl5 joint at rest, where it stands) are pinned, held by the pelvis unless
/// attach_to says otherwise: how trousers and skirts modelled on the body stay up.
void ParseWaistband(const Field& field, const GarmentContext& context, sim::GarmentSpec& garment) {
  const double band = ReadNumber(field, {0.0, 0.5, true, false}, "m");
  if (!garment.mesh || !context.avatar) {
    field.Refuse("needs [garment.mesh] and an [avatar] whose waist it is held at", "m");
  }
  const sim::Skeleton& skeleton = context.avatar->avatar->skeleton();
  const int vl5 = skeleton.Find(sim::HAnimJoint::kVl5);
  if (vl5 < 0) field.Refuse("the avatar has no joint mapped onto vl5 (the waist)", "m");
  const double waist = skeleton.rest_world()[vl5].translation().y() +
                       context.avatar->motion.posture.root_translation.y();
  garment.pin_points = sim::WaistbandPoints(*garment.mesh, waist, band);
  if (garment.pin_points.empty()) {
    field.Refuse("no open edge of the mesh lies within " + FormatValue(band) +
                 " m of the waist at y = " + FormatValue(waist) + " m", "m");
  }
  if (!garment.attach_to) garment.attach_to = sim::HAnimJoint::kSacroiliac;
}

sim::GarmentSpec ParseGarment(const TableView& table, const GarmentContext& context) {
  const std::vector<std::string>& materials = context.materials;
  table.RefuseUnknownKeys({"name", "material", "pin_points", "pin_waistband", "pin_tolerance",
                           "attach_to", "panel", "mesh", "pattern", "resolution"});
  sim::GarmentSpec garment;
  garment.source_line = table.line();
  garment.name = ReadName(table.Require("name"));
  if (const std::optional<Field> material = table.Find("material")) {
    garment.material = ReadName(*material);
    if (std::find(materials.begin(), materials.end(), garment.material) == materials.end()) {
      material->Refuse("unknown material; the known materials are " + Join(materials));
    }
  }
  if (const std::optional<Field> pins = table.Find("pin_points")) {
    garment.pin_points = ReadPoints(*pins, "m");
  }
  garment.pin_tolerance = NumberOr(table, "pin_tolerance", garment.pin_tolerance, kPositive, "m");
  if (const std::optional<Field> attach = table.Find("attach_to")) {
    garment.attach_to = sim::ParseHAnimName(ReadName(*attach));
    if (!garment.attach_to) {
      std::vector<std::string> names;
      for (sim::HAnimJoint joint : sim::AllHAnimJoints()) names.push_back(Quote(sim::HAnimName(joint)));
      attach->Refuse("not an H-Anim joint; the joints are " + Join(names));
    }
  }
  const std::optional<TableView> panel = FindTable(table, "panel", "[garment.panel]");
  const std::optional<TableView> mesh = FindTable(table, "mesh", "[garment.mesh]");
  const std::optional<Field> pattern = table.Find("pattern");
  if (panel.has_value() + mesh.has_value() + pattern.has_value() != 1) {
    table.Refuse(table.name() + " " + Quote(garment.name) +
                 ": needs exactly one of [garment.panel], [garment.mesh] and pattern = \"...\"");
  }
  if (panel) garment.panel = ParsePanel(*panel);
  if (mesh) {
    garment.mesh = ParseMesh(*mesh, context.makehuman_body);
    garment.fit_outside_body = BoolOr(*mesh, "fit_outside_body", false);
  }
  if (const std::optional<Field> waistband = table.Find("pin_waistband")) {
    if (table.Find("pin_points")) {
      waistband->Refuse("give pin_points or pin_waistband, not both", "m");
    }
    ParseWaistband(*waistband, context, garment);
  }
  if (pattern) {
    garment.pattern = ReadChoice(*pattern, {"skirt", "cape", "dress"});
    garment.pattern_resolution = IntegerOr(table, "resolution", garment.pattern_resolution, 8, 1024);
  }
  return garment;
}

std::vector<sim::GarmentSpec> ParseGarments(const TableView& root,
                                            const GarmentContext& context) {
  std::vector<sim::GarmentSpec> garments;
  std::map<std::string, toml::source_position> seen;
  for (const TableView& table : FindTableArray(root, "garment", "[[garment]]")) {
    garments.push_back(ParseGarment(table, context));
    RefuseDuplicateName(seen, table.Require("name"), garments.back().name, "garment");
  }
  if (garments.empty()) root.Refuse("garment: missing; a scene needs at least one [[garment]]");
  return garments;
}

sim::SphereObstacleSpec ParseSphere(const TableView& table) {
  table.RefuseUnknownKeys({"center", "radius", "thickness", "friction"});
  sim::SphereObstacleSpec sphere;
  sphere.source_line = table.line();
  sphere.center = Vector3Or(table, "center", sphere.center, "m", kCoordinateRange);
  sphere.radius =
      NumberOr(table, "radius", sphere.radius, {0.0, sim::kMaxCoordinate, true, false}, "m");
  sphere.thickness = NumberOr(table, "thickness", sphere.thickness, kThicknessRange, "m");
  sphere.friction = NumberOr(table, "friction", sphere.friction, kFrictionRange, "");
  return sphere;
}

/// The file a `model` or `clip` field names, relative to the scene file's folder. Refused
/// when the scene may not name files (AvatarFiles::kRefused) or there is no such file: the
/// message lists `built_ins` first, since a misspelt built-in is the likelier mistake, then
/// `file_kind` ("an avatar file (.glb ...)").
std::string AvatarFilePath(const Field& field, const std::string& value,
                           const std::vector<std::string>& built_ins,
                           const std::string& file_kind) {
  std::vector<std::string> quoted;
  for (const std::string& name : built_ins) quoted.push_back(Quote(name));
  if (field.source->avatar_files == AvatarFiles::kRefused) {
    field.Refuse("must be one of " + Join(quoted) +
                 " here: a garment file names no avatar or clip file (the catalogue holds "
                 "those as entries of their own)");
  }
  const std::string path = ResolvePath(field.source->base_dir, value);
  std::error_code error;
  if (!std::filesystem::exists(path, error)) {
    field.Refuse("must be one of " + Join(quoted) + ", or " + file_kind + "; no file " +
                 Quote(path));
  }
  return path;
}

/// `clip`: "none", a built-in clip (made on `skeleton`), or a clip file (BVH, glTF/GLB, FBX,
/// Collada, DeepMimic), retargeted onto the avatar when played.
std::shared_ptr<const sim::Clip> ParseClip(const Field& field,
                                           std::shared_ptr<const sim::Skeleton> skeleton) {
  std::vector<std::string> choices = {"none"};
  for (const std::string& name : sim::BuiltInClipNames()) choices.push_back(name);
  const std::string value = ReadName(field);
  if (value == "none") return nullptr;
  if (std::find(choices.begin(), choices.end(), value) != choices.end()) {
    return std::make_shared<const sim::Clip>(sim::MakeBuiltInClip(value, std::move(skeleton)));
  }
  const std::string path = AvatarFilePath(
      field, value, choices, "a clip file (.bvh .glb .gltf .fbx .dae, DeepMimic .txt)");
  return std::make_shared<const sim::Clip>(ImportAt(field, path, [&] { return LoadClip(path); }));
}

/// Refuses, at the `clip` field, a clip that cannot be put on the avatar (too few H-Anim
/// joints mapped on either skeleton): the build would refuse it later, without a line.
void RequirePlayable(const Field& clip, const sim::AvatarSpec& avatar) {
  if (!avatar.clip) return;
  try {
    const sim::Retargeter retargeter(avatar.clip->skeleton, avatar.avatar->shared_skeleton());
  } catch (const InputError& error) {
    clip.Refuse(std::string("cannot be put on the avatar: ") + error.what());
  }
}

/// `model`: "builtin", an avatar file (glTF/GLB, FBX, Collada, OBJ), or MakeHuman's base
/// mesh when `skeleton` (.mhskel) and `weights` (.mhw) are given too (its path then goes to
/// `makehuman_body`, which MakeHuman's garments are fitted to).
std::shared_ptr<const sim::Avatar> ParseModel(const TableView& table,
                                              std::string& makehuman_body) {
  const std::optional<Field> model = table.Find("model");
  const std::optional<Field> skeleton = table.Find("skeleton");
  const std::optional<Field> weights = table.Find("weights");
  const std::string value = model ? ReadName(*model) : "builtin";
  if (value == "builtin") {
    if (skeleton || weights) {
      (skeleton ? *skeleton : *weights)
          .Refuse("only with a MakeHuman model file (model = \"base.obj\")");
    }
    return sim::MakeHumanoid();
  }
  const std::string path =
      AvatarFilePath(*model, value, {"builtin"}, "an avatar file (.glb .gltf .fbx .dae .obj)");
  if (!skeleton && !weights) {
    return ImportAt(*model, path, [&] { return LoadAvatar(path); });
  }
  if (!skeleton || !weights) {
    (skeleton ? *skeleton : *weights).Refuse("a MakeHuman model needs both skeleton and weights");
  }
  const std::string skeleton_path = ResolvePath(table.source().base_dir, ReadName(*skeleton));
  const std::string weights_path = ResolvePath(table.source().base_dir, ReadName(*weights));
  makehuman_body = path;
  return ImportAt(*model, path, [&] {
    return LoadMakeHumanAvatar(path, skeleton_path, weights_path);
  });
}

/// [avatar.posture]: joint rotations in degrees, [x, y, z] about the joint's rest axes
/// applied in that order, keyed by H-Anim name; joints not named keep the rest pose.
void ParsePosture(const TableView& table, const sim::Skeleton& skeleton, sim::Pose& posture) {
  std::vector<std::string> names;
  for (sim::HAnimJoint joint : sim::AllHAnimJoints()) names.emplace_back(sim::HAnimName(joint));
  const std::vector<std::string_view> allowed(names.begin(), names.end());
  table.RefuseUnknownKeys(allowed);
  posture.rotations.assign(skeleton.num_joints(), Eigen::Quaterniond::Identity());
  for (sim::HAnimJoint joint : sim::AllHAnimJoints()) {
    const std::optional<Field> field = table.Find(sim::HAnimName(joint));
    if (!field) continue;
    const Eigen::Vector3d angles = ReadVector3(*field, "degrees", kPostureRange);
    const int index = skeleton.Find(joint);
    if (index < 0) field->Refuse("the avatar has no joint mapped onto this H-Anim joint");
    posture.rotations[index] = sim::PostureRotation(angles);
  }
}

/// `arm_spread`: "auto" (the default: the simulation chooses it, sim_core/scene/arm_spread.h)
/// or degrees turning both of the clip's arms away from the body (0: as retargeted).
void ParseArmSpread(const TableView& table, sim::AvatarSpec& avatar) {
  const std::optional<Field> field = table.Find("arm_spread");
  if (!field) return;
  if (field->node->as_string()) {
    ReadChoice(*field, {"auto"});
    return;
  }
  const double degrees =
      ReadNumber(*field, {0.0, sim::kMaxArmSpreadDegrees, false, false}, "degrees");
  avatar.auto_arm_spread = false;
  avatar.motion.arm_spread.fill(degrees * M_PI / 180.0);
}

/// [avatar]: the avatar (built-in or a file), the clip it plays, how cloth collides with it.
sim::AvatarSpec ParseAvatar(const TableView& table, std::string& makehuman_body) {
  table.RefuseUnknownKeys({"model", "skeleton", "weights", "clip", "collision",
                           "superquadric_map_mb", "thickness", "friction", "max_skin_travel",
                           "max_steps_per_frame", "fit_time", "blend_time", "position",
                           "heading", "posture", "arm_spread"});
  sim::AvatarSpec avatar;
  avatar.source_line = table.line();
  avatar.avatar = ParseModel(table, makehuman_body);
  if (const std::optional<Field> clip = table.Find("clip")) {
    // Built-in clips are written for the built-in humanoid's skeleton (the avatar's own when
    // it is that humanoid) and retargeted onto any other avatar when played, as file clips.
    const std::optional<Field> model = table.Find("model");
    const bool built_in = !model || ReadName(*model) == "builtin";
    avatar.clip = ParseClip(*clip, built_in ? avatar.avatar->shared_skeleton()
                                            : sim::MakeHumanoidSkeleton());
    RequirePlayable(*clip, avatar);
  }
  if (const std::optional<Field> collision = table.Find("collision")) {
    avatar.collision = ReadChoice(*collision, {"superquadric", "mesh"}) == "mesh"
                           ? sim::BodyCollisionMethod::kMesh
                           : sim::BodyCollisionMethod::kSuperquadric;
  }
  avatar.superquadric_map_mb = NumberOr(table, "superquadric_map_mb", avatar.superquadric_map_mb,
                                        {0.0, sim::kMaxSuperquadricMapMb, false, false}, "MB");
  avatar.thickness = NumberOr(table, "thickness", avatar.thickness, kThicknessRange, "m");
  avatar.friction = NumberOr(table, "friction", avatar.friction, kFrictionRange, "");
  avatar.max_skin_travel =
      NumberOr(table, "max_skin_travel", avatar.max_skin_travel, {0.0, 1.0, false, false}, "m");
  avatar.max_steps_per_frame = IntegerOr(table, "max_steps_per_frame", avatar.max_steps_per_frame,
                                         1, sim::kMaxStepsPerFrame);
  avatar.motion.fit_time =
      NumberOr(table, "fit_time", avatar.motion.fit_time, {0.0, 60.0, false, false}, "s");
  avatar.motion.blend_time =
      NumberOr(table, "blend_time", avatar.motion.blend_time, {0.0, 60.0, false, false}, "s");
  ParseArmSpread(table, avatar);
  avatar.motion.posture.root_translation =
      Vector3Or(table, "position", Eigen::Vector3d::Zero(), "m", kCoordinateRange);
  const double heading = NumberOr(table, "heading", 0.0, kPostureRange, "degrees");
  avatar.motion.posture.orientation = sim::PostureRotation({0.0, heading, 0.0});
  if (const std::optional<TableView> posture = FindTable(table, "posture", "[avatar.posture]")) {
    ParsePosture(*posture, avatar.avatar->skeleton(), avatar.motion.posture);
  }
  return avatar;
}

/// The scene's name when the file gives none: the file name without folder and extension.
std::string DefaultSceneName(const std::string& source_name) {
  const std::string stem = std::filesystem::path(source_name).stem().string();
  return stem.empty() ? std::string("scene") : stem;
}

sim::SceneDescription ParseScene(const TableView& root) {
  root.RefuseUnknownKeys({"name", "duration", "frame_rate", "gravity", "solver", "effects",
                          "material", "garment", "sphere", "avatar"});
  sim::SceneDescription scene;
  scene.source = root.source().name;
  scene.name = DefaultSceneName(scene.source);
  if (const std::optional<Field> name = root.Find("name")) scene.name = ReadName(*name);
  scene.duration = NumberOr(root, "duration", scene.duration, kDurationRange, "s");
  scene.frame_rate = NumberOr(root, "frame_rate", scene.frame_rate, kFrameRateRange, "Hz");
  scene.gravity = Vector3Or(root, "gravity", scene.gravity, "m/s²", kGravityRange);
  if (const std::optional<TableView> solver = FindTable(root, "solver", "[solver]")) {
    scene.solver = ParseSolver(*solver);
  }
  if (const std::optional<TableView> effects = FindTable(root, "effects", "[effects]")) {
    scene.effects = ParseEffects(*effects);
  }
  std::string makehuman_body;  // base.obj when the avatar is MakeHuman's (.mhclo garments)
  if (const std::optional<TableView> avatar = FindTable(root, "avatar", "[avatar]")) {
    scene.avatar = ParseAvatar(*avatar, makehuman_body);
  }
  scene.materials = ParseMaterials(root);
  GarmentContext garments{KnownMaterialNames(scene.materials),
                          scene.avatar ? &*scene.avatar : nullptr, makehuman_body};
  scene.garments = ParseGarments(root, garments);
  for (const TableView& table : FindTableArray(root, "sphere", "[[sphere]]")) {
    scene.spheres.push_back(ParseSphere(table));
  }
  return scene;
}

/// Parses TOML, turning syntax errors into InputError with file:line:column.
toml::table ParseToml(const std::string& text, const Source& source) {
  try {
    return toml::parse(std::string_view(text), std::string_view(source.name));
  } catch (const toml::parse_error& error) {
    throw InputError(At(source, error.source().begin) +
                     ": TOML syntax error: " + std::string(error.description()));
  }
}

std::vector<std::string> QuotedBuiltInNames() {
  std::vector<std::string> names;
  for (const BuiltInScene& scene : kBuiltInScenes) names.push_back(Quote(scene.name));
  return names;
}

}  // namespace

sim::SceneDescription LoadSceneFile(const std::string& path, AvatarFiles avatar_files) {
  const std::string text = ReadWholeFile(path, "scene file");
  return ParseSceneText(text, path, std::filesystem::path(path).parent_path().string(),
                        avatar_files);
}

sim::SceneDescription ParseSceneText(const std::string& text, const std::string& source_name,
                                     const std::string& base_dir, AvatarFiles avatar_files) {
  const Source source{source_name, base_dir, avatar_files};
  const toml::table root = ParseToml(text, source);
  sim::SceneDescription scene = ParseScene(TableView(root, "", "the top level", {1, 1}, source));
  // Everything ValidateScene checks was checked above with a line number; this keeps the
  // promise that a parsed scene is valid even if the two ever drift apart.
  sim::ValidateScene(scene);
  return scene;
}

std::vector<std::string> BuiltInSceneNames() {
  std::vector<std::string> names;
  for (const BuiltInScene& scene : kBuiltInScenes) names.emplace_back(scene.name);
  return names;
}

std::string BuiltInSceneText(const std::string& name) {
  for (const BuiltInScene& scene : kBuiltInScenes) {
    if (scene.name == name) return std::string(scene.text);
  }
  throw InputError("unknown built-in scene " + Quote(name) + "; the built-in scenes are " +
                   Join(QuotedBuiltInNames()));
}

sim::SceneDescription LoadBuiltInScene(const std::string& name) {
  return ParseSceneText(BuiltInSceneText(name), "built-in:" + name, "");
}

}  // namespace costume::assets
