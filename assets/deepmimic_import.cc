#include "assets/deepmimic_import.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "assets/skeleton_families.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {
namespace {

using nlohmann::json;
using sim::InputError;

constexpr int kMaxJoints = 1000;
constexpr std::size_t kMaxFrames = 10000000;

json ParseJson(const std::string& path, const std::string& what) {
  const std::string text = ReadWholeFile(path, what);
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(path + ": not valid JSON (" + e.what() + ")");
  }
}

const json& Field(const std::string& where, const json& object, const char* name,
                  json::value_t type) {
  if (!object.is_object() || !object.contains(name)) {
    throw InputError(where + ": missing field '" + name + "'");
  }
  const json& value = object.at(name);
  const bool ok = type == json::value_t::number_float ? value.is_number() : value.type() == type;
  if (!ok) throw InputError(where + ": field '" + name + "' has the wrong type (" + value.type_name() + ")");
  return value;
}

double Number(const std::string& where, const json& object, const char* name) {
  const double value = Field(where, object, name, json::value_t::number_float).get<double>();
  sim::RequireFinite(where + ": " + name, value, "");
  return value;
}

double NumberOr(const std::string& where, const json& object, const char* name, double fallback) {
  return object.contains(name) ? Number(where, object, name) : fallback;
}

enum class JointType { kNone, kSpherical, kRevolute, kFixed };

struct CharacterJoint {
  std::string name;
  JointType type = JointType::kNone;
  int parent = -1;
  Eigen::Isometry3d attach = Eigen::Isometry3d::Identity();
};

int NumValues(JointType type) {
  return type == JointType::kSpherical ? 4 : type == JointType::kRevolute ? 1 : 0;
}

std::vector<CharacterJoint> ReadJoints(const std::string& path, const json& root, double scale) {
  const json& skeleton = Field(path, root, "Skeleton", json::value_t::object);
  const json& list = Field(path + ": Skeleton", skeleton, "Joints", json::value_t::array);
  if (list.empty() || list.size() > kMaxJoints) {
    throw InputError(path + ": Skeleton.Joints has " + std::to_string(list.size()) +
                     " joints (allowed: 1.." + std::to_string(kMaxJoints) + ")");
  }
  std::vector<CharacterJoint> joints;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = path + ": Skeleton.Joints[" + std::to_string(i) + "]";
    const json& item = list[i];
    const double id = Number(where, item, "ID");
    if (id != static_cast<double>(i)) {
      throw InputError(where + ": ID " + sim::FormatValue(id) + " (allowed: " + std::to_string(i) +
                       ", joints listed in ID order)");
    }
    CharacterJoint joint;
    joint.name = Field(where, item, "Name", json::value_t::string).get<std::string>();
    const std::string type = Field(where, item, "Type", json::value_t::string).get<std::string>();
    if (type == "none") joint.type = JointType::kNone;
    else if (type == "spherical") joint.type = JointType::kSpherical;
    else if (type == "revolute") joint.type = JointType::kRevolute;
    else if (type == "fixed") joint.type = JointType::kFixed;
    else throw InputError(where + ": Type '" + type + "' (allowed: none, spherical, revolute, fixed)");
    const double parent = Number(where, item, "Parent");
    if (parent != std::floor(parent) || parent < -1 || parent >= static_cast<double>(i) ||
        (parent < 0) != (i == 0)) {
      throw InputError(where + ": Parent " + sim::FormatValue(parent) + " (allowed: -1 for joint 0, else 0.." +
                       std::to_string(static_cast<int>(i) - 1) + ")");
    }
    joint.parent = static_cast<int>(parent);
    joint.attach.translation() = scale * Eigen::Vector3d(Number(where, item, "AttachX"),
                                                         Number(where, item, "AttachY"),
                                                         Number(where, item, "AttachZ"));
    joint.attach.linear() =
        (Eigen::AngleAxisd(NumberOr(where, item, "AttachThetaZ", 0), Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(NumberOr(where, item, "AttachThetaY", 0), Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(NumberOr(where, item, "AttachThetaX", 0), Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    joints.push_back(std::move(joint));
  }
  return joints;
}

/// How far below the root the character reaches in its rest pose [m] (positive).
double DepthBelowRoot(const std::string& path, const json& root,
                      const std::vector<Eigen::Isometry3d>& world, double scale) {
  double lowest = 0.0;
  for (const Eigen::Isometry3d& frame : world) lowest = std::min(lowest, frame.translation().y());
  if (!root.contains("BodyDefs") || !root.at("BodyDefs").is_array()) return -lowest;
  const json& bodies = root.at("BodyDefs");
  for (std::size_t b = 0; b < bodies.size() && b < world.size(); ++b) {
    const std::string where = path + ": BodyDefs[" + std::to_string(b) + "]";
    const json& body = bodies[b];
    if (!body.is_object() || !body.contains("Shape")) continue;
    const std::string shape = Field(where, body, "Shape", json::value_t::string).get<std::string>();
    const double centre = (world[b] * (scale * Eigen::Vector3d(NumberOr(where, body, "AttachX", 0),
                                                               NumberOr(where, body, "AttachY", 0),
                                                               NumberOr(where, body, "AttachZ", 0))))
                              .y();
    const double p0 = scale * NumberOr(where, body, "Param0", 0);
    const double p1 = scale * NumberOr(where, body, "Param1", 0);
    // DeepMimic sizes: box Param0..2 = extents, sphere Param0 = diameter, capsule
    // Param0 = diameter and Param1 = length of the straight part.
    const double reach = shape == "box" ? p1 / 2 : shape == "sphere" ? p0 / 2
                                                   : shape == "capsule" ? (p0 + p1) / 2 : 0.0;
    lowest = std::min(lowest, centre - reach);
  }
  return -lowest;
}

std::shared_ptr<const sim::Skeleton> BuildSkeleton(const std::string& path, const json& root,
                                                   double scale,
                                                   std::vector<CharacterJoint>& character) {
  character = ReadJoints(path, root, scale);
  std::vector<Eigen::Isometry3d> world(character.size());
  for (std::size_t j = 0; j < character.size(); ++j) {
    world[j] = character[j].parent < 0 ? character[j].attach
                                       : world[character[j].parent] * character[j].attach;
  }
  const double depth = DepthBelowRoot(path, root, world, scale);
  std::vector<sim::Joint> joints(character.size());
  for (std::size_t j = 0; j < character.size(); ++j) {
    joints[j].name = character[j].name;
    joints[j].parent = character[j].parent;
    joints[j].rest_local = character[j].attach;
  }
  joints[0].rest_local.translation() += Eigen::Vector3d(0.0, depth, 0.0);
  MapToHAnim(joints);
  try {
    return sim::Skeleton::Create(std::filesystem::path(path).stem().string(), std::move(joints));
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

Eigen::Quaterniond ReadQuaternion(const std::string& where, const json& frame, std::size_t at) {
  const Eigen::Quaterniond q(frame[at].get<double>(), frame[at + 1].get<double>(),
                             frame[at + 2].get<double>(), frame[at + 3].get<double>());
  if (q.norm() < 0.5 || q.norm() > 2.0) {
    throw InputError(where + ", values " + std::to_string(at) + ".." + std::to_string(at + 3) +
                     ": quaternion of norm " + sim::FormatValue(q.norm()) +
                     " (allowed: a rotation, norm near 1)");
  }
  return q.normalized();
}

/// One frame's pose; `frame` holds only finite numbers of the right count.
sim::Pose ReadPose(const std::string& where, const json& frame,
                   const std::vector<CharacterJoint>& character, const sim::Skeleton& skeleton,
                   double scale) {
  sim::Pose pose = sim::RestPose(skeleton);
  const Eigen::Vector3d position(frame[1].get<double>(), frame[2].get<double>(),
                                 frame[3].get<double>());
  pose.root_translation = scale * position - skeleton.joint(0).rest_local.translation();
  pose.rotations[0] = ReadQuaternion(where, frame, 4);
  std::size_t at = 8;
  for (std::size_t j = 1; j < character.size(); ++j) {
    if (character[j].type == JointType::kSpherical) {
      pose.rotations[j] = ReadQuaternion(where, frame, at);
    } else if (character[j].type == JointType::kRevolute) {
      pose.rotations[j] = Eigen::AngleAxisd(frame[at].get<double>(), Eigen::Vector3d::UnitZ());
    }
    at += NumValues(character[j].type);
  }
  return pose;
}

void CheckFrame(const std::string& where, const json& frame, std::size_t expected) {
  if (!frame.is_array() || frame.size() != expected) {
    throw InputError(where + ": " + (frame.is_array() ? std::to_string(frame.size()) + " values"
                                                      : std::string("not an array")) +
                     " (allowed: " + std::to_string(expected) +
                     " = dt, root position 3, root quaternion 4, then the joints')");
  }
  for (std::size_t i = 0; i < frame.size(); ++i) {
    if (!frame[i].is_number() || !std::isfinite(frame[i].get<double>())) {
      throw InputError(where + ", value " + std::to_string(i) + ": not a finite number");
    }
  }
}

}  // namespace

std::string DeepMimicCharacterPath(const std::string& motion, const ClipImportOptions& options) {
  if (!options.deepmimic_character.empty()) return options.deepmimic_character;
  return (std::filesystem::path(motion).parent_path() / ".." / "characters" / "humanoid3d.txt")
      .lexically_normal()
      .string();
}

std::shared_ptr<const sim::Skeleton> LoadDeepMimicSkeleton(const std::string& path, double scale) {
  std::vector<CharacterJoint> character;
  return BuildSkeleton(path, ParseJson(path, "DeepMimic character file"), scale, character);
}

sim::Clip LoadDeepMimicClip(const std::string& path, const ClipImportOptions& options) {
  ValidateClipOptions(path, options);
  const double scale = options.scale > 0.0 ? options.scale : 1.0;
  const json motion = ParseJson(path, "DeepMimic motion file");
  const std::string loop = Field(path, motion, "Loop", json::value_t::string).get<std::string>();
  if (loop != "wrap" && loop != "none") {
    throw InputError(path + ": Loop '" + loop + "' (allowed: wrap, none)");
  }
  const json& frames = Field(path, motion, "Frames", json::value_t::array);
  if (frames.empty() || frames.size() > kMaxFrames) {
    throw InputError(path + ": Frames has " + std::to_string(frames.size()) +
                     " frames (allowed: 1.." + std::to_string(kMaxFrames) + ")");
  }

  const std::string character_path = DeepMimicCharacterPath(path, options);
  std::vector<CharacterJoint> character;
  sim::Clip clip;
  clip.skeleton = BuildSkeleton(character_path, ParseJson(character_path, "DeepMimic character file"),
                                scale, character);
  std::size_t expected = 8;
  for (std::size_t j = 1; j < character.size(); ++j) expected += NumValues(character[j].type);

  const bool wrap = loop == "wrap";
  clip.loops = options.loops.value_or(wrap);
  const std::size_t used = (clip.loops && wrap && frames.size() > 1) ? frames.size() - 1 : frames.size();
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const std::string where = path + ": Frames[" + std::to_string(f) + "]";
    CheckFrame(where, frames[f], expected);
    const double dt = frames[f][0].get<double>();
    if (f + 1 < frames.size() || frames.size() == 1) {
      if (f == 0) clip.frame_time = dt;
      if (!(dt > 0.0) || std::abs(dt - clip.frame_time) > 0.01 * clip.frame_time) {
        throw InputError(where + ": dt " + sim::FormatValue(dt) + " s (allowed: > 0 and within 1 % of the first frame's " +
                         sim::FormatValue(clip.frame_time) + " s)");
      }
    }
    if (f < used) clip.frames.push_back(ReadPose(where, frames[f], character, *clip.skeleton, scale));
  }
  clip.name = options.name.empty() ? std::filesystem::path(path).stem().string() : options.name;
  clip.category = options.category;
  clip.provenance = path + " (character " + character_path + ")";
  if (options.start_at_origin) MoveStartToOrigin(clip);
  sim::ValidateClip(clip);
  return clip;
}

}  // namespace costume::assets
