#include "assets/clip_import.h"

#include <algorithm>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <string>
#include <unordered_map>

#include "assets/assimp_skeleton.h"
#include "assets/bvh_import.h"
#include "assets/deepmimic_import.h"
#include "assets/import_units.h"
#include "assets/skeleton_families.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {
namespace {

using sim::InputError;

/// Tolerances of the loop test: a clip whose end pose is this close to its start pose loops.
constexpr double kLoopAngle = 10.0 * M_PI / 180.0;
constexpr double kLoopDistance = 0.05;
/// More frames than this is a damaged file or a wrong time unit, not a clip.
constexpr double kMaxFrames = 1e6;

/// Index of the last key at or before `time` (0 if none is).
template <typename Key>
unsigned KeyBefore(const Key* keys, unsigned count, double time) {
  unsigned lo = 0, hi = count;
  while (hi - lo > 1) {
    const unsigned mid = (lo + hi) / 2;
    (keys[mid].mTime <= time ? lo : hi) = mid;
  }
  return lo;
}

/// Where between keys `k` and `k + 1` the time lies, in [0, 1].
template <typename Key>
double Fraction(const Key* keys, unsigned count, unsigned k, double time) {
  if (k + 1 >= count) return 0.0;
  const double span = keys[k + 1].mTime - keys[k].mTime;
  return span > 0.0 ? std::clamp((time - keys[k].mTime) / span, 0.0, 1.0) : 0.0;
}

Eigen::Vector3d ToEigen3(const aiVector3D& v) { return {v.x, v.y, v.z}; }

/// The node's local transform at `time` [ticks] from its channel (keys clamped at the ends).
Eigen::Matrix4d ChannelTransform(const aiNodeAnim& channel, double time) {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d scaling = Eigen::Vector3d::Ones();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  if (channel.mNumPositionKeys > 0) {
    const unsigned k = KeyBefore(channel.mPositionKeys, channel.mNumPositionKeys, time);
    const double t = Fraction(channel.mPositionKeys, channel.mNumPositionKeys, k, time);
    const unsigned k1 = std::min(k + 1, channel.mNumPositionKeys - 1);
    position = (1 - t) * ToEigen3(channel.mPositionKeys[k].mValue) +
               t * ToEigen3(channel.mPositionKeys[k1].mValue);
  }
  if (channel.mNumScalingKeys > 0) {
    const unsigned k = KeyBefore(channel.mScalingKeys, channel.mNumScalingKeys, time);
    const double t = Fraction(channel.mScalingKeys, channel.mNumScalingKeys, k, time);
    const unsigned k1 = std::min(k + 1, channel.mNumScalingKeys - 1);
    scaling = (1 - t) * ToEigen3(channel.mScalingKeys[k].mValue) +
              t * ToEigen3(channel.mScalingKeys[k1].mValue);
  }
  if (channel.mNumRotationKeys > 0) {
    const unsigned k = KeyBefore(channel.mRotationKeys, channel.mNumRotationKeys, time);
    const double t = Fraction(channel.mRotationKeys, channel.mNumRotationKeys, k, time);
    const unsigned k1 = std::min(k + 1, channel.mNumRotationKeys - 1);
    const aiQuaternion& a = channel.mRotationKeys[k].mValue;
    const aiQuaternion& b = channel.mRotationKeys[k1].mValue;
    rotation = Eigen::Quaterniond(a.w, a.x, a.y, a.z)
                   .normalized()
                   .slerp(t, Eigen::Quaterniond(b.w, b.x, b.y, b.z).normalized());
  }
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();
  transform.topLeftCorner<3, 3>() = rotation.toRotationMatrix() * scaling.asDiagonal();
  transform.topRightCorner<3, 1>() = position;
  return transform;
}

/// The joint whose path a clip's root translation follows: the H-Anim root when the
/// skeleton's family maps one (joints' hanim set), else the skeleton's root. Unreal's and
/// Character Creator's rigs keep a root on the floor, still or carrying root motion alone,
/// and move the pelvis below it up and down.
int PathJoint(const std::vector<sim::Joint>& joints) {
  for (int j = 0; j < static_cast<int>(joints.size()); ++j) {
    if (joints[j].hanim == sim::HAnimJoint::kHumanoidRoot) return j;
  }
  return 0;
}

/// Samples one animation of an assimp scene onto the skeleton of its nodes.
class AnimationSampler {
 public:
  AnimationSampler(const aiAnimation& animation, const AssimpSkeleton& skeleton,
                   const Eigen::Matrix4d& file_to_world)
      : skeleton_(skeleton),
        file_to_world_(file_to_world),
        path_joint_(PathJoint(skeleton.joints)) {
    for (unsigned c = 0; c < animation.mNumChannels; ++c) {
      channels_[animation.mChannels[c]->mNodeName.C_Str()] = animation.mChannels[c];
    }
  }

  /// The skeleton's pose at `time` [ticks].
  sim::Pose PoseAt(double time) const {
    const int n = static_cast<int>(skeleton_.joints.size());
    std::vector<Eigen::Isometry3d> world(n);
    sim::Pose pose;
    pose.rotations.resize(n);
    for (int j = 0; j < n; ++j) {
      world[j] = RigidPart(file_to_world_ * Global(skeleton_.nodes[j], time));
      const sim::Joint& joint = skeleton_.joints[j];
      const Eigen::Isometry3d rest =
          joint.parent < 0 ? joint.rest_local : world[joint.parent] * joint.rest_local;
      pose.rotations[j] = Eigen::Quaterniond(rest.linear().transpose() * world[j].linear()).normalized();
    }
    // A pose moves the root only; the path joint's own motion (a pelvis's bob under a still
    // root) is kept by moving the root so that the path joint lands where the file puts it.
    pose.root_translation =
        world[path_joint_].translation() - PlacedWithoutTranslation(world, path_joint_);
    return pose;
  }

 private:
  /// Where joint `j` lands with the joints turned as `world` turns them and the root not
  /// moved from its rest place.
  Eigen::Vector3d PlacedWithoutTranslation(const std::vector<Eigen::Isometry3d>& world,
                                           int j) const {
    const sim::Joint& joint = skeleton_.joints[j];
    if (joint.parent < 0) return joint.rest_local.translation();
    return PlacedWithoutTranslation(world, joint.parent) +
           world[joint.parent].linear() * joint.rest_local.translation();
  }

  Eigen::Matrix4d Global(const aiNode* node, double time) const {
    Eigen::Matrix4d global = Eigen::Matrix4d::Identity();
    for (; node != nullptr; node = node->mParent) {
      const auto channel = channels_.find(node->mName.C_Str());
      global = (channel == channels_.end() ? ToEigen(node->mTransformation)
                                           : ChannelTransform(*channel->second, time)) *
               global;
    }
    return global;
  }

  const AssimpSkeleton& skeleton_;
  Eigen::Matrix4d file_to_world_;
  int path_joint_ = 0;
  std::unordered_map<std::string, const aiNodeAnim*> channels_;
};

/// Throws InputError naming the file, the node, the key list and the key unless every key's
/// time is finite and not before the one before it, and `problem` finds nothing wrong with
/// its value (it returns what is wrong, or ""). Sampling would otherwise drop such keys
/// without a word: a zero or NaN quaternion became the rest rotation, and NaN or decreasing
/// times left a clip of one frame.
template <typename Key, typename Problem>
void ValidateKeys(const std::string& where, const char* list, const Key* keys, unsigned count,
                  const Problem& problem) {
  for (unsigned k = 0; k < count; ++k) {
    const std::string key = where + " " + list + " key " + std::to_string(k);
    const double time = keys[k].mTime;
    if (!std::isfinite(time) || (k > 0 && time < keys[k - 1].mTime)) {
      throw InputError(key + ": time " + sim::FormatValue(time) +
                       " ticks (allowed: finite, not before the key before it)");
    }
    if (const std::string wrong = problem(keys[k].mValue); !wrong.empty()) {
      throw InputError(key + ": " + wrong);
    }
  }
}

void ValidateChannel(const std::string& path, const aiNodeAnim& channel) {
  const std::string where = path + ": node '" + channel.mNodeName.C_Str() + "'";
  const auto finite = [](const aiVector3D& v) -> std::string {
    if (std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z)) return "";
    return sim::FormatValues({v.x, v.y, v.z}) + " (allowed: finite numbers)";
  };
  ValidateKeys(where, "position", channel.mPositionKeys, channel.mNumPositionKeys, finite);
  ValidateKeys(where, "scaling", channel.mScalingKeys, channel.mNumScalingKeys, finite);
  ValidateKeys(where, "rotation", channel.mRotationKeys, channel.mNumRotationKeys,
               [](const aiQuaternion& q) -> std::string {
                 const double norm = std::sqrt(double{q.w} * q.w + double{q.x} * q.x +
                                               double{q.y} * q.y + double{q.z} * q.z);
                 if (std::isfinite(norm) && norm > 1e-6) return "";
                 return "(w, x, y, z) = " + sim::FormatValues({q.w, q.x, q.y, q.z}) +
                        " is not a rotation (allowed: a finite quaternion of non-zero length)";
               });
}

bool PosesMatch(const sim::Pose& a, const sim::Pose& b) {
  for (std::size_t j = 0; j < a.rotations.size(); ++j) {
    if (a.rotations[j].angularDistance(b.rotations[j]) > kLoopAngle) return false;
  }
  return (a.root_translation - b.root_translation).norm() <= kLoopDistance;
}

/// The height of the rest skeleton in file units turned y up (for guessing the unit).
double SkeletonHeight(const AssimpSkeleton& skeleton) {
  double lowest = INFINITY, highest = -INFINITY;
  for (const Eigen::Isometry3d& frame : skeleton.rest_world) {
    lowest = std::min(lowest, frame.translation().y());
    highest = std::max(highest, frame.translation().y());
  }
  return highest - lowest;
}

sim::Clip LoadAssimpClip(const std::string& path, const ClipImportOptions& options) {
  Assimp::Importer importer;
  const aiScene* scene =
      ReadAssimpScene(importer, path, aiProcess_ValidateDataStructure, "animation file");
  if (scene->mNumAnimations == 0) throw InputError(path + ": the file holds no animation");
  if (options.animation >= static_cast<int>(scene->mNumAnimations)) {
    throw InputError(path + ": animation " + std::to_string(options.animation) +
                     " out of range (allowed: 0.." + std::to_string(scene->mNumAnimations - 1) +
                     ")");
  }
  const aiAnimation& animation = *scene->mAnimations[options.animation];
  for (unsigned c = 0; c < animation.mNumChannels; ++c) {
    ValidateChannel(path, *animation.mChannels[c]);
  }
  UpAxis up = options.up != UpAxis::kAuto ? options.up : DeclaredUp(*scene, path);
  if (up == UpAxis::kAuto) up = UpAxis::kY;
  double scale = options.scale > 0.0 ? options.scale : DeclaredMetresPerUnit(*scene, path);
  if (scale <= 0.0) {
    scale = GuessMetresPerUnit(
        SkeletonHeight(CollectSkeleton(*scene, FileToWorld(1.0, up), options.animation)));
  }
  const Eigen::Matrix4d file_to_world = FileToWorld(scale, up);
  AssimpSkeleton skeleton = CollectSkeleton(*scene, file_to_world, options.animation);
  if (skeleton.joints.empty()) throw InputError(path + ": the animation moves no node");

  // assimp reports 0 ticks per second when the file does not say; its convention is 25.
  const double ticks_per_second = animation.mTicksPerSecond > 0.0 ? animation.mTicksPerSecond : 25.0;
  const double duration = animation.mDuration / ticks_per_second;
  if (!std::isfinite(duration) || duration < 0.0 || duration > 1e6) {
    throw InputError(path + ": animation duration " + sim::FormatValue(duration) +
                     " s (allowed: 0..1e6)");
  }
  if (duration * options.sample_rate > kMaxFrames) {
    throw InputError(path + ": animation of " + sim::FormatValue(duration) + " s at " +
                     sim::FormatValue(options.sample_rate) + " Hz exceeds " +
                     sim::FormatValue(kMaxFrames) + " frames");
  }
  MapToHAnim(skeleton.joints);  // before sampling: the H-Anim root's path is the clip's
  const AnimationSampler sampler(animation, skeleton, file_to_world);
  const int intervals = std::max(1, static_cast<int>(std::lround(duration * options.sample_rate)));
  const sim::Pose first = sampler.PoseAt(0.0);
  const bool loops = options.loops.value_or(duration > 0.0 &&
                                            PosesMatch(first, sampler.PoseAt(animation.mDuration)));

  sim::Clip clip;
  clip.name = options.name.empty() ? std::filesystem::path(path).stem().string() : options.name;
  clip.category = options.category;
  clip.loops = loops;
  clip.provenance = path;
  clip.frame_time = duration > 0.0 ? duration / intervals : 1.0 / options.sample_rate;
  const int num_frames = duration > 0.0 ? (loops ? intervals : intervals + 1) : 1;
  for (int f = 0; f < num_frames; ++f) {
    clip.frames.push_back(sampler.PoseAt(animation.mDuration * f / intervals));
  }
  clip.skeleton = sim::Skeleton::Create(clip.name, std::move(skeleton.joints));
  if (options.start_at_origin) MoveStartToOrigin(clip);
  sim::ValidateClip(clip);
  return clip;
}

}  // namespace

void ValidateClipOptions(const std::string& path, const ClipImportOptions& options) {
  ValidateScaleOption(path, options.scale);
  sim::RequireInRange(path + ": sample_rate", options.sample_rate, 1.0, 1000.0, "Hz");
  if (options.animation < 0) {
    throw InputError(path + ": animation " + std::to_string(options.animation) +
                     " out of range (allowed: >= 0)");
  }
}

void MoveStartToOrigin(sim::Clip& clip) {
  if (clip.frames.empty()) return;
  Eigen::Vector3d start = clip.frames.front().root_translation;
  start.y() = 0.0;
  for (sim::Pose& pose : clip.frames) pose.root_translation -= start;
}

sim::Clip LoadClip(const std::string& path, const ClipImportOptions& options) {
  ValidateClipOptions(path, options);
  const std::string extension = LowerExtension(path);
  try {
    if (extension == ".bvh") return LoadBvhClip(path, options);
    if (extension == ".txt" || extension == ".json") return LoadDeepMimicClip(path, options);
    return LoadAssimpClip(path, options);
  } catch (const InputError& e) {
    const std::string message = e.what();
    if (message.find(path) != std::string::npos) throw;
    throw InputError(path + ": " + message);
  }
}

}  // namespace costume::assets
