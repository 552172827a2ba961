#include "assets/makehuman_import.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "assets/import_units.h"
#include "assets/skeleton_families.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/garment_fit.h"

namespace costume::assets {
namespace {

using nlohmann::json;
using sim::InputError;

json ParseJson(const std::string& path, const std::string& what) {
  const std::string text = ReadWholeFile(path, what);
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(path + ": not valid JSON (" + e.what() + ")");
  }
}

const json& Field(const std::string& where, const json& object, const char* name) {
  if (!object.is_object() || !object.contains(name)) {
    throw InputError(where + ": missing field '" + name + "'");
  }
  return object.at(name);
}

double ParseNumber(const std::string& where, const std::string& word) {
  char* end = nullptr;
  const double value = std::strtod(word.c_str(), &end);
  if (word.empty() || end != word.c_str() + word.size() || !std::isfinite(value)) {
    throw InputError(where + ": '" + sim::QuoteForMessage(word) + "' is not a finite number");
  }
  return value;
}

/// One face corner "7", "7/3", "7//2", "-1/…" → 0-based vertex index.
int ParseCorner(const std::string& where, const std::string& word, int num_vertices) {
  const std::string index = word.substr(0, word.find('/'));
  const double value = ParseNumber(where, index);
  const double resolved = value < 0 ? num_vertices + value : value - 1;
  if (value == 0 || value != std::floor(value) || resolved < 0 || resolved >= num_vertices) {
    throw InputError(where + ": face index " + sim::QuoteForMessage(index) +
                     " out of range (allowed: 1.." + std::to_string(num_vertices) + " or -1..-" +
                     std::to_string(num_vertices) + " for the vertices read so far)");
  }
  return static_cast<int>(resolved);
}

Eigen::Vector3d Centroid(const std::string& where, const json& refs, const ObjMesh& obj) {
  if (!refs.is_array() || refs.empty()) throw InputError(where + ": not a non-empty array");
  // Three non-integer numbers are a position; integers are base-mesh vertex indices.
  const bool is_position = refs.size() == 3 && std::any_of(refs.begin(), refs.end(), [](const json& v) {
                             return v.is_number_float();
                           });
  if (is_position) {
    Eigen::Vector3d p;
    for (int c = 0; c < 3; ++c) p[c] = refs[c].get<double>();
    if (!p.allFinite()) throw InputError(where + ": non-finite position");
    return p;
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const json& ref : refs) {
    if (!ref.is_number_integer() || ref.get<long>() < 0 || ref.get<long>() >= obj.vertices.rows()) {
      throw InputError(where + ": vertex index " + sim::QuoteForMessage(ref.dump()) +
                       " out of range (allowed: 0.." + std::to_string(obj.vertices.rows() - 1) + ")");
    }
    sum += obj.vertices.row(ref.get<long>()).transpose();
  }
  return sum / static_cast<double>(refs.size());
}

struct Bone {
  std::string name;
  std::string parent;
  Eigen::Vector3d head, tail;
  std::optional<Eigen::Vector3d> normal;
};

/// MakeHuman's bone roll: the normal of the plane through three joints.
std::optional<Eigen::Vector3d> PlaneNormal(const std::string& where, const json& planes,
                                           const std::string& name,
                                           const std::map<std::string, Eigen::Vector3d>& joints) {
  if (!planes.is_object() || !planes.contains(name)) return std::nullopt;
  const json& plane = planes.at(name);
  if (!plane.is_array() || plane.size() != 3) throw InputError(where + ": plane '" + name + "' is not 3 joints");
  Eigen::Vector3d p[3];
  for (int k = 0; k < 3; ++k) {
    const auto found = plane[k].is_string() ? joints.find(plane[k].get<std::string>()) : joints.end();
    if (found == joints.end()) throw InputError(where + ": plane '" + name + "' names an unknown joint");
    p[k] = found->second;
  }
  const Eigen::Vector3d normal = (p[2] - p[1]).normalized().cross((p[1] - p[0]).normalized());
  if (!(normal.norm() > 1e-6)) return std::nullopt;
  return normal.normalized();
}

/// The bone's frame: origin at the head, y towards the tail, x along the roll normal.
Eigen::Isometry3d BoneFrame(const Bone& bone, double scale) {
  const Eigen::Vector3d y = (bone.tail - bone.head).normalized();
  Eigen::Vector3d normal = bone.normal.value_or(Eigen::Vector3d::UnitX());
  if (std::abs(normal.dot(y)) > 0.99) {
    normal = std::abs(y.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ();
  }
  const Eigen::Vector3d z = normal.cross(y).normalized();
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear().col(0) = y.cross(z);
  frame.linear().col(1) = y;
  frame.linear().col(2) = z;
  frame.translation() = scale * bone.head;
  return frame;
}

std::vector<Bone> ReadBones(const std::string& path, const json& root, const ObjMesh& obj) {
  const json& joint_refs = Field(path, root, "joints");
  if (!joint_refs.is_object()) throw InputError(path + ": 'joints' is not an object");
  std::map<std::string, Eigen::Vector3d> joints;
  for (const auto& [name, refs] : joint_refs.items()) {
    joints[name] = Centroid(path + ": joints." + name, refs, obj);
  }
  const json planes = root.contains("planes") ? root.at("planes") : json::object();
  const json& bones = Field(path, root, "bones");
  if (!bones.is_object() || bones.empty()) throw InputError(path + ": 'bones' is not a non-empty object");
  std::vector<Bone> result;
  for (const auto& [name, item] : bones.items()) {
    const std::string where = path + ": bones." + name;
    Bone bone;
    bone.name = name;
    const json& parent = Field(where, item, "parent");
    if (!parent.is_null() && !parent.is_string()) throw InputError(where + ": parent is not a name or null");
    bone.parent = parent.is_string() ? parent.get<std::string>() : "";
    for (const char* end : {"head", "tail"}) {
      const json& ref = Field(where, item, end);
      const auto found = ref.is_string() ? joints.find(ref.get<std::string>()) : joints.end();
      if (found == joints.end()) throw InputError(where + ": " + end + " names no entry of 'joints'");
      (std::string(end) == "head" ? bone.head : bone.tail) = found->second;
    }
    if (!((bone.tail - bone.head).norm() > 1e-9)) throw InputError(where + ": head and tail coincide");
    if (item.contains("rotation_plane") && item.at("rotation_plane").is_string()) {
      bone.normal = PlaneNormal(where, planes, item.at("rotation_plane").get<std::string>(), joints);
    }
    result.push_back(std::move(bone));
  }
  return result;
}

/// Orders bones parents first; throws for unknown parents and cycles.
std::vector<Bone> ParentsFirst(const std::string& path, std::vector<Bone> bones) {
  std::vector<Bone> ordered;
  std::map<std::string, int> placed;
  while (!bones.empty()) {
    const std::size_t before = bones.size();
    for (auto it = bones.begin(); it != bones.end();) {
      if (it->parent.empty() || placed.count(it->parent)) {
        placed[it->name] = static_cast<int>(ordered.size());
        ordered.push_back(std::move(*it));
        it = bones.erase(it);
      } else {
        ++it;
      }
    }
    if (bones.size() == before) {
      throw InputError(path + ": bones." + bones.front().name + ": parent '" + bones.front().parent +
                       "' is not a bone, or the parents form a cycle");
    }
  }
  return ordered;
}

}  // namespace

ObjMesh ReadObj(const std::string& path) {
  std::istringstream stream(ReadWholeFile(path, "OBJ file"));
  std::vector<Eigen::Vector3d> vertices;
  ObjMesh mesh;
  std::string group = "default";
  std::string line;
  for (int number = 1; std::getline(stream, line); ++number) {
    const std::string where = path + ":" + std::to_string(number);
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "v") {
      Eigen::Vector3d v;
      for (int c = 0; c < 3; ++c) {
        std::string word;
        if (!(words >> word)) throw InputError(where + ": a vertex needs 3 coordinates");
        v[c] = ParseNumber(where, word);
      }
      vertices.push_back(v);
    } else if (keyword == "g") {
      words >> group;
    } else if (keyword == "f") {
      std::vector<int> face;
      for (std::string word; words >> word;) {
        face.push_back(ParseCorner(where, word, static_cast<int>(vertices.size())));
      }
      if (face.size() < 3) {
        throw InputError(where + ": face of " + std::to_string(face.size()) + " corners (allowed: 3 or more)");
      }
      mesh.faces.push_back(std::move(face));
      mesh.face_groups.push_back(group);
    }
  }
  if (vertices.empty()) throw InputError(path + ": no vertices ('v' lines)");
  mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    mesh.vertices.row(static_cast<Eigen::Index>(v)) = vertices[v].transpose();
  }
  return mesh;
}

std::shared_ptr<const sim::Skeleton> LoadMakeHumanSkeleton(const std::string& path,
                                                           const ObjMesh& obj, double scale) {
  sim::RequirePositive(path + ": scale", scale, "m per file unit");
  const json root = ParseJson(path, "MakeHuman skeleton file");
  const std::vector<Bone> bones = ParentsFirst(path, ReadBones(path, root, obj));
  std::vector<sim::Joint> joints(bones.size());
  std::vector<Eigen::Isometry3d> world(bones.size());
  std::map<std::string, int> index;
  for (std::size_t b = 0; b < bones.size(); ++b) {
    index[bones[b].name] = static_cast<int>(b);
    world[b] = BoneFrame(bones[b], scale);
    joints[b].name = bones[b].name;
    joints[b].parent = bones[b].parent.empty() ? -1 : index.at(bones[b].parent);
    joints[b].rest_local = joints[b].parent < 0 ? world[b] : world[joints[b].parent].inverse() * world[b];
  }
  MapToHAnim(joints);
  const std::string name = root.contains("name") && root.at("name").is_string()
                               ? root.at("name").get<std::string>() : "makehuman";
  try {
    return sim::Skeleton::Create(name, std::move(joints));
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

namespace {

/// Per kept vertex, its (joint, weight) pairs from the .mhw file.
std::vector<std::vector<std::pair<int, double>>> ReadWeights(const std::string& path,
                                                             const sim::Skeleton& skeleton,
                                                             const std::vector<int>& kept_index,
                                                             int num_kept) {
  const json root = ParseJson(path, "MakeHuman weights file");
  const json& weights = Field(path, root, "weights");
  if (!weights.is_object()) throw InputError(path + ": 'weights' is not an object");
  std::vector<std::vector<std::pair<int, double>>> influences(num_kept);
  for (const auto& [bone, list] : weights.items()) {
    const std::string where = path + ": weights." + bone;
    const int joint = skeleton.FindByName(bone);
    if (joint < 0) throw InputError(where + ": no bone of that name in the skeleton");
    if (!list.is_array()) throw InputError(where + ": not an array of [vertex, weight]");
    for (std::size_t k = 0; k < list.size(); ++k) {
      const json& pair = list[k];
      const std::string at = where + "[" + std::to_string(k) + "]";
      if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_integer() || !pair[1].is_number()) {
        throw InputError(at + ": not a [vertex index, weight] pair");
      }
      const long vertex = pair[0].get<long>();
      const double weight = pair[1].get<double>();
      if (vertex < 0 || vertex >= static_cast<long>(kept_index.size())) {
        throw InputError(at + ": vertex index " + std::to_string(vertex) + " out of range (allowed: 0.." +
                         std::to_string(kept_index.size() - 1) + ")");
      }
      // MakeHuman writes weights of 0.001 to 1; a damaged 2147483648 would take the vertex
      // wholly to its bone after the renormalisation, without a word.
      if (!(weight >= 0.0 && weight <= 1.0)) {
        throw InputError(at + ": weight " + sim::FormatValue(weight) + " (allowed: [0, 1])");
      }
      if (kept_index[vertex] >= 0 && weight > 0.0) influences[kept_index[vertex]].emplace_back(joint, weight);
    }
  }
  return influences;
}

void FillInfluences(std::vector<std::vector<std::pair<int, double>>>& all, int root,
                    sim::AvatarData& data) {
  const Eigen::Index n = static_cast<Eigen::Index>(all.size());
  data.influence_joints.setConstant(n, sim::kMaxInfluences, -1);
  data.influence_weights.setZero(n, sim::kMaxInfluences);
  for (Eigen::Index v = 0; v < n; ++v) {
    auto& list = all[v];
    if (list.empty()) list.emplace_back(root, 1.0);
    std::sort(list.begin(), list.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    list.resize(std::min<std::size_t>(list.size(), sim::kMaxInfluences));
    double sum = 0.0;
    for (const auto& entry : list) sum += entry.second;
    for (std::size_t k = 0; k < list.size(); ++k) {
      data.influence_joints(v, static_cast<Eigen::Index>(k)) = list[k].first;
      data.influence_weights(v, static_cast<Eigen::Index>(k)) = list[k].second / sum;
    }
  }
}

}  // namespace

std::shared_ptr<const sim::Avatar> LoadMakeHumanAvatar(const std::string& obj_path,
                                                       const std::string& skeleton_path,
                                                       const std::string& weights_path,
                                                       const MakeHumanImportOptions& options) {
  sim::RequirePositive(obj_path + ": scale", options.scale, "m per file unit");
  const ObjMesh obj = ReadObj(obj_path);
  sim::AvatarData data;
  data.name = options.name;
  data.provenance = obj_path + " + " + skeleton_path + " + " + weights_path;
  data.skeleton = LoadMakeHumanSkeleton(skeleton_path, obj, options.scale);

  std::vector<int> kept_index(obj.vertices.rows(), -1);
  std::vector<int> kept;
  for (std::size_t f = 0; f < obj.faces.size(); ++f) {
    if (!options.groups.empty() &&
        std::find(options.groups.begin(), options.groups.end(), obj.face_groups[f]) == options.groups.end()) {
      continue;
    }
    std::vector<int> corners;
    for (int v : obj.faces[f]) {
      if (kept_index[v] < 0) {
        kept_index[v] = -2;  // placeholder: numbered below, in file order
      }
      corners.push_back(v);
    }
    for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
      data.triangles.emplace_back(corners[0], corners[k], corners[k + 1]);
    }
  }
  for (int v = 0; v < static_cast<int>(kept_index.size()); ++v) {
    if (kept_index[v] == -2) {
      kept_index[v] = static_cast<int>(kept.size());
      kept.push_back(v);
    }
  }
  if (kept.empty()) throw InputError(obj_path + ": no face in the groups asked for");
  for (Eigen::Vector3i& triangle : data.triangles) {
    for (int c = 0; c < 3; ++c) triangle[c] = kept_index[triangle[c]];
  }
  data.rest_vertices.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t v = 0; v < kept.size(); ++v) {
    data.rest_vertices.row(static_cast<Eigen::Index>(v)) = options.scale * obj.vertices.row(kept[v]);
  }
  auto influences = ReadWeights(weights_path, *data.skeleton, kept_index, static_cast<int>(kept.size()));
  FillInfluences(influences, 0, data);
  return sim::Avatar::Create(std::move(data));
}

namespace {

/// A body vertex index of a .mhclo line, checked against the body.
int BodyVertex(const std::string& where, const std::string& word, const ObjMesh& body) {
  const double value = ParseNumber(where, word);
  if (value != std::floor(value) || value < 0 || value >= body.vertices.rows()) {
    throw InputError(where + ": body vertex " + word + " out of range (allowed: 0.." +
                     std::to_string(body.vertices.rows() - 1) + ")");
  }
  return static_cast<int>(value);
}

/// How far a .mhclo row's three weights may sum from 1 (MakeHuman's files: 1e-5).
constexpr double kMhcloWeightSumTolerance = 1e-3;

/// What a .mhclo file says about fitting its garment.
struct MhcloFit {
  std::string obj_file;
  /// Per axis: the body's size over the garment's reference size [-].
  Eigen::Vector3d axis_scale = Eigen::Vector3d::Constant(-1.0);
  /// Per garment vertex, in file units of the body.
  std::vector<Eigen::Vector3d> positions;
};

/// One "verts" row: "i" (the body vertex itself) or "i j k wi wj wk dx dy dz".
Eigen::Vector3d FitRow(const std::string& where, const std::vector<std::string>& words,
                       const ObjMesh& body, const Eigen::Vector3d& axis_scale) {
  if (words.size() == 1) return body.vertices.row(BodyVertex(where, words[0], body)).transpose();
  if (words.size() != 9) {
    throw InputError(where + ": a vertex row has " + std::to_string(words.size()) +
                     " numbers (allowed: 1, or 3 body vertices, 3 weights, 3 offsets)");
  }
  // An affine combination: MakeHuman's weights reach -1.04 and 2.73 but sum to 1 within
  // its 5 decimals. Weights summing elsewhere scale the vertex away from the body.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double weight = ParseNumber(where, words[3 + k]);
    sum += weight;
    position += weight * body.vertices.row(BodyVertex(where, words[k], body)).transpose();
  }
  if (!(std::abs(sum - 1.0) <= kMhcloWeightSumTolerance)) {
    throw InputError(where + ": the weights " + words[3] + ", " + words[4] + ", " + words[5] +
                     " sum to " + sim::FormatValue(sum) + " (allowed: 1 ± " +
                     sim::FormatValue(kMhcloWeightSumTolerance) + ")");
  }
  for (int axis = 0; axis < 3; ++axis) {
    position[axis] += axis_scale[axis] * ParseNumber(where, words[6 + axis]);
  }
  return position;
}

/// Refuses a fitted vertex (file units) farther from the body's box than the box's diagonal:
/// clothes lie within centimetres of the body, so such a row (a huge offset, or weights that
/// sum to 1 but reach far outside the body) is a damaged file, as is a non-finite one.
void RequireNearTheBody(const std::string& where, const Eigen::Vector3d& position,
                        const Eigen::AlignedBox3d& body_box) {
  const double distance = body_box.exteriorDistance(position);
  const double allowed = body_box.diagonal().norm();
  if (!(distance <= allowed)) {
    throw InputError(where + ": the row puts its vertex " + sim::FormatValue(distance) +
                     " file units from the body's bounding box (allowed: within its diagonal, " +
                     sim::FormatValue(allowed) + ")");
  }
}

/// The word after "obj_file" on a .mhclo line; empty for other lines.
std::string ObjFileOf(const std::string& line) {
  std::istringstream split(line);
  std::string key, name, extra;
  if (!(split >> key >> name) || key != "obj_file" || (split >> extra)) return "";
  return name;
}

MhcloFit ReadMhclo(const std::string& path, const ObjMesh& body) {
  std::istringstream stream(ReadWholeFile(path, "MakeHuman clothes file"));
  MhcloFit fit;
  const Eigen::AlignedBox3d body_box(body.vertices.colwise().minCoeff().transpose(),
                                     body.vertices.colwise().maxCoeff().transpose());
  bool in_verts = false;
  std::string line;
  for (int number = 1; std::getline(stream, line); ++number) {
    const std::string where = path + ":" + std::to_string(number);
    std::istringstream split(line);
    std::vector<std::string> words;
    for (std::string word; split >> word;) words.push_back(word);
    if (words.empty() || words[0][0] == '#') continue;
    const bool numeric = std::isdigit(static_cast<unsigned char>(words[0][0])) != 0;
    if (in_verts && numeric) {
      if (fit.axis_scale.minCoeff() <= 0.0) {
        throw InputError(where + ": vertex rows before the x_scale, y_scale and z_scale lines");
      }
      fit.positions.push_back(FitRow(where, words, body, fit.axis_scale));
      RequireNearTheBody(where, fit.positions.back(), body_box);
      continue;
    }
    in_verts = words[0] == "verts";
    const int axis = words[0] == "x_scale" ? 0 : words[0] == "y_scale" ? 1 : words[0] == "z_scale" ? 2 : -1;
    if (axis >= 0) {
      if (words.size() != 4) throw InputError(where + ": " + words[0] + " needs 2 body vertices and a distance");
      const double reference = ParseNumber(where, words[3]);
      const double size = std::abs(body.vertices(BodyVertex(where, words[1], body), axis) -
                                   body.vertices(BodyVertex(where, words[2], body), axis));
      if (!(reference > 0.0) || !(size > 0.0)) {
        throw InputError(where + ": " + words[0] + " distances must be > 0 (body " +
                         sim::FormatValue(size) + ", reference " + sim::FormatValue(reference) + ")");
      }
      fit.axis_scale[axis] = size / reference;
    } else if (const std::string obj = ObjFileOf(line); !obj.empty()) {
      fit.obj_file = obj;
    }
  }
  if (fit.obj_file.empty()) throw InputError(path + ": missing 'obj_file' line");
  return fit;
}

}  // namespace

sim::SurfaceMesh LoadMakeHumanGarment(const std::string& mhclo_path, const ObjMesh& body,
                                      double scale) {
  sim::RequirePositive(mhclo_path + ": scale", scale, "m per file unit");
  const MhcloFit fit = ReadMhclo(mhclo_path, body);
  const std::string obj_path = (std::filesystem::path(mhclo_path).parent_path() / fit.obj_file).string();
  const ObjMesh garment = ReadObj(obj_path);
  if (static_cast<Eigen::Index>(fit.positions.size()) != garment.vertices.rows()) {
    throw InputError(mhclo_path + ": " + std::to_string(fit.positions.size()) +
                     " vertex rows for the " + std::to_string(garment.vertices.rows()) +
                     " vertices of " + obj_path + " (they must agree)");
  }
  sim::SurfaceMesh mesh;
  mesh.source = mhclo_path;
  mesh.faces = garment.faces;
  mesh.vertices.resize(garment.vertices.rows(), 3);
  for (std::size_t v = 0; v < fit.positions.size(); ++v) {
    mesh.vertices.row(static_cast<Eigen::Index>(v)) = scale * fit.positions[v].transpose();
  }
  return mesh;
}

std::string MakeHumanGarmentObjFile(const std::string& mhclo_path) {
  std::istringstream stream(ReadWholeFile(mhclo_path, "MakeHuman clothes file"));
  for (std::string line; std::getline(stream, line);) {
    if (std::string obj = ObjFileOf(line); !obj.empty()) return obj;
  }
  throw InputError(mhclo_path + ": missing 'obj_file' line");
}

sim::GarmentSpec MakeHumanGarmentSpec(const std::string& mhclo_path, const ObjMesh& body,
                                      const sim::Skeleton& skeleton) {
  const int vl5 = skeleton.Find(sim::HAnimJoint::kVl5);
  if (vl5 < 0) {
    throw InputError(mhclo_path +
                     ": the MakeHuman skeleton has no joint mapped onto vl5 "
                     "(the waist its waistband is held at)");
  }
  sim::GarmentSpec garment;
  garment.mesh = sim::WeldShortEdges(LoadMakeHumanGarment(mhclo_path, body), kMakeHumanGarmentWeld);
  const double waist = skeleton.rest_world()[vl5].translation().y();
  garment.pin_points = sim::WaistbandPoints(*garment.mesh, waist, kMakeHumanWaistband);
  if (!garment.pin_points.empty()) garment.attach_to = sim::HAnimJoint::kSacroiliac;
  garment.fit_outside_body = true;
  return garment;
}

}  // namespace costume::assets
