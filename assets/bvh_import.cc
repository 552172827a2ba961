#include "assets/bvh_import.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "assets/skeleton_families.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {
namespace {

using sim::InputError;

constexpr int kMaxJoints = 10000;
constexpr long kMaxFrames = 10000000;
constexpr double kDegrees = M_PI / 180.0;
/// The largest rotation a channel may hold [degrees]. Angles unwrapped over a long capture
/// pass 360 by some turns, but none a capture writes comes near 1e5 (278 turns); a value of
/// 1e308, made by damaging a file at random, turned the joint to an arbitrary angle for a
/// frame, which imported without a word.
constexpr double kMaxRotationDegrees = 1e5;

/// The file split into whitespace-separated words, each with its line number.
class Tokens {
 public:
  Tokens(std::string path, const std::string& text) : path_(std::move(path)) {
    int line = 1;
    std::size_t i = 0;
    while (i < text.size()) {
      const char c = text[i];
      if (c == '\n') ++line;
      if (std::isspace(static_cast<unsigned char>(c))) {
        ++i;
        continue;
      }
      const std::size_t start = i;
      while (i < text.size() && !std::isspace(static_cast<unsigned char>(text[i]))) ++i;
      words_.push_back(text.substr(start, i - start));
      lines_.push_back(line);
    }
  }

  bool done() const { return next_ >= words_.size(); }
  const std::string& Peek() const {
    static const std::string kEnd = "<end of file>";
    return done() ? kEnd : words_[next_];
  }
  /// The line of the next word (the last line at the end of the file).
  int line() const { return lines_.empty() ? 1 : lines_[std::min(next_, lines_.size() - 1)]; }
  std::string Where() const { return path_ + ":" + std::to_string(line()); }

  std::string Take(const std::string& what) {
    if (done()) throw InputError(Where() + ": file ends where " + what + " was expected");
    return words_[next_++];
  }
  void Expect(const std::string& word) {
    const std::string found = Take("'" + word + "'");
    if (found != word) {
      --next_;
      throw InputError(Where() + ": expected '" + word + "', found '" +
                       sim::QuoteForMessage(found) + "'");
    }
  }
  double TakeNumber(const std::string& what) {
    const std::string word = Take(what);
    char* end = nullptr;
    const double value = std::strtod(word.c_str(), &end);
    if (end != word.c_str() + word.size() || !std::isfinite(value)) {
      --next_;
      throw InputError(Where() + ": " + what + " is '" + sim::QuoteForMessage(word) +
                       "' (allowed: a finite number)");
    }
    return value;
  }
  /// Throws InputError placed at the word just taken, which `message` describes.
  [[noreturn]] void RefuseLast(const std::string& message) {
    --next_;
    throw InputError(Where() + ": " + message);
  }
  long TakeInteger(const std::string& what, long lo, long hi) {
    const double value = TakeNumber(what);
    if (value != std::floor(value) || value < lo || value > hi) {
      --next_;
      throw InputError(Where() + ": " + what + " is " + sim::FormatValue(value) +
                       " (allowed: an integer in " + std::to_string(lo) + ".." +
                       std::to_string(hi) + ")");
    }
    return static_cast<long>(value);
  }

 private:
  std::string path_;
  std::vector<std::string> words_;
  std::vector<int> lines_;
  std::size_t next_ = 0;
};

enum class Channel { kXpos, kYpos, kZpos, kXrot, kYrot, kZrot };

struct BvhJoint {
  std::string name;
  int parent = -1;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  std::vector<Channel> channels;
  int first_channel = 0;
};

struct BvhFile {
  std::vector<BvhJoint> joints;
  /// End Site offsets with their joint: only for the rest height.
  std::vector<std::pair<int, Eigen::Vector3d>> end_sites;
  int num_channels = 0;
  long num_frames = 0;
  double frame_time = 0.0;
  std::vector<double> values;  // num_frames × num_channels
};

constexpr std::pair<const char*, Channel> kChannelNames[] = {
    {"Xposition", Channel::kXpos}, {"Yposition", Channel::kYpos}, {"Zposition", Channel::kZpos},
    {"Xrotation", Channel::kXrot}, {"Yrotation", Channel::kYrot}, {"Zrotation", Channel::kZrot}};

const char* ChannelName(Channel channel) {
  for (const auto& [name, c] : kChannelNames) {
    if (c == channel) return name;
  }
  return "?";
}

bool IsRotation(Channel channel) {
  return channel == Channel::kXrot || channel == Channel::kYrot || channel == Channel::kZrot;
}

Channel ParseChannel(Tokens& tokens) {
  const std::string word = tokens.Take("a channel name");
  for (const auto& [name, channel] : kChannelNames) {
    if (word.size() == std::string_view(name).size() &&
        std::equal(word.begin(), word.end(), name, [](char a, char b) {
          return std::tolower(static_cast<unsigned char>(a)) ==
                 std::tolower(static_cast<unsigned char>(b));
        })) {
      return channel;
    }
  }
  throw InputError(tokens.Where() + ": unknown channel '" + sim::QuoteForMessage(word) +
                   "' (allowed: Xposition Yposition Zposition Xrotation Yrotation Zrotation)");
}

Eigen::Vector3d ParseOffset(Tokens& tokens) {
  tokens.Expect("OFFSET");
  Eigen::Vector3d offset;
  for (int c = 0; c < 3; ++c) offset[c] = tokens.TakeNumber("OFFSET value");
  return offset;
}

/// Parses the joints after HIERARCHY, iteratively (a deep file must not overflow the stack).
void ParseHierarchy(Tokens& tokens, BvhFile& file) {
  tokens.Expect("HIERARCHY");
  std::vector<int> open;  // joints whose '}' is pending
  while (true) {
    const std::string word = tokens.Take("ROOT, JOINT, End Site, '}' or MOTION");
    if (word == "MOTION" && open.empty() && !file.joints.empty()) return;
    if (word == "}" && !open.empty()) {
      open.pop_back();
      continue;
    }
    if (word == "End" && !open.empty()) {
      tokens.Expect("Site");
      tokens.Expect("{");
      file.end_sites.emplace_back(open.back(), ParseOffset(tokens));
      tokens.Expect("}");
      continue;
    }
    const bool is_root = word == "ROOT" && open.empty();
    if (!is_root && !(word == "JOINT" && !open.empty())) {
      throw InputError(tokens.Where() + ": unexpected '" + sim::QuoteForMessage(word) + "'" +
                       (open.empty() ? " (expected ROOT or MOTION)"
                                     : " (expected JOINT, End Site or '}')"));
    }
    if (static_cast<int>(file.joints.size()) >= kMaxJoints) {
      throw InputError(tokens.Where() + ": more than " + std::to_string(kMaxJoints) + " joints");
    }
    BvhJoint joint;
    joint.name = tokens.Take("a joint name");
    joint.parent = open.empty() ? -1 : open.back();
    tokens.Expect("{");
    joint.offset = ParseOffset(tokens);
    if (tokens.Peek() == "CHANNELS") {
      tokens.Take("CHANNELS");
      const long n = tokens.TakeInteger("CHANNELS count", 0, 6);
      for (long c = 0; c < n; ++c) joint.channels.push_back(ParseChannel(tokens));
    }
    joint.first_channel = file.num_channels;
    file.num_channels += static_cast<int>(joint.channels.size());
    open.push_back(static_cast<int>(file.joints.size()));
    file.joints.push_back(std::move(joint));
  }
}

void ParseMotion(Tokens& tokens, BvhFile& file) {
  tokens.Expect("Frames:");
  file.num_frames = tokens.TakeInteger("Frames", 1, kMaxFrames);
  tokens.Expect("Frame");
  tokens.Expect("Time:");
  file.frame_time = tokens.TakeNumber("Frame Time");
  if (!(file.frame_time >= sim::kMinFrameTime && file.frame_time <= sim::kMaxFrameTime)) {
    tokens.RefuseLast("Frame Time is " + sim::FormatValue(file.frame_time) + " s (allowed: [" +
                      sim::FormatValue(sim::kMinFrameTime) + ", " +
                      sim::FormatValue(sim::kMaxFrameTime) + "])");
  }
  // Per value of a frame, its joint and channel, for the messages.
  std::vector<std::pair<const BvhJoint*, Channel>> columns;
  for (const BvhJoint& joint : file.joints) {
    for (Channel channel : joint.channels) columns.emplace_back(&joint, channel);
  }
  const long total = file.num_frames * file.num_channels;
  file.values.reserve(static_cast<std::size_t>(std::min<long>(total, 100000000)));
  for (long i = 0; i < total; ++i) {
    if (tokens.done()) {
      throw InputError(tokens.Where() + ": file ends in frame " +
                       std::to_string(i / std::max(1, file.num_channels)) + " of " +
                       std::to_string(file.num_frames) + " (header says " +
                       std::to_string(file.num_frames) + " frames of " +
                       std::to_string(file.num_channels) + " values)");
    }
    const double value = tokens.TakeNumber("channel value");
    const auto& [joint, channel] = columns[static_cast<std::size_t>(i % file.num_channels)];
    if (IsRotation(channel) && !(std::abs(value) <= kMaxRotationDegrees)) {
      tokens.RefuseLast("frame " + std::to_string(i / file.num_channels) + ", joint '" +
                        sim::QuoteForMessage(joint->name) + "' " + ChannelName(channel) + " = " +
                        sim::FormatValue(value) + " degrees (allowed: within ±" +
                        sim::FormatValue(kMaxRotationDegrees) + ")");
    }
    file.values.push_back(value);
  }
  if (!tokens.done()) {
    throw InputError(tokens.Where() + ": '" + sim::QuoteForMessage(tokens.Peek()) +
                     "' after the last of " + std::to_string(file.num_frames) +
                     " frames (the Frames: count does not match the data)");
  }
}

/// Rest positions of the joints and end sites relative to the first root, file units.
std::vector<Eigen::Vector3d> RestPoints(const BvhFile& file, std::vector<Eigen::Vector3d>& joint_points) {
  joint_points.resize(file.joints.size());
  for (std::size_t j = 0; j < file.joints.size(); ++j) {
    const BvhJoint& joint = file.joints[j];
    joint_points[j] = joint.parent < 0 ? Eigen::Vector3d(Eigen::Vector3d::Zero())
                                       : Eigen::Vector3d(joint_points[joint.parent] + joint.offset);
  }
  std::vector<Eigen::Vector3d> all = joint_points;
  for (const auto& [joint, offset] : file.end_sites) all.push_back(joint_points[joint] + offset);
  return all;
}

/// The up axis: the declared one, else the axis along which the head stands from the root.
UpAxis DetectUp(const BvhFile& file, const std::vector<Eigen::Vector3d>& joint_points,
                UpAxis declared) {
  if (declared != UpAxis::kAuto) return declared;
  std::vector<sim::Joint> joints(file.joints.size());
  for (std::size_t j = 0; j < joints.size(); ++j) joints[j].name = file.joints[j].name;
  MapToHAnim(joints);
  int root = -1, top = -1;
  for (int j = 0; j < static_cast<int>(joints.size()); ++j) {
    if (joints[j].hanim == sim::HAnimJoint::kHumanoidRoot) root = j;
    if (joints[j].hanim == sim::HAnimJoint::kSkullbase ||
        (top < 0 && joints[j].hanim == sim::HAnimJoint::kVc7)) {
      top = j;
    }
  }
  if (root < 0 || top < 0) return UpAxis::kY;
  const Eigen::Vector3d up = joint_points[top] - joint_points[root];
  return std::abs(up.z()) > std::abs(up.y()) ? UpAxis::kZ : UpAxis::kY;
}

Eigen::Quaterniond FrameRotation(const BvhJoint& joint, const double* values) {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  for (std::size_t c = 0; c < joint.channels.size(); ++c) {
    const double angle = values[joint.first_channel + c] * kDegrees;
    switch (joint.channels[c]) {
      case Channel::kXrot: rotation = rotation * Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()); break;
      case Channel::kYrot: rotation = rotation * Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()); break;
      case Channel::kZrot: rotation = rotation * Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()); break;
      default: break;
    }
  }
  return rotation;
}

/// The root's position in the frame: its position channels where it has them, its
/// OFFSET for the axes it has none.
Eigen::Vector3d FramePosition(const BvhJoint& joint, const double* values) {
  Eigen::Vector3d position = joint.offset;
  for (std::size_t c = 0; c < joint.channels.size(); ++c) {
    const double value = values[joint.first_channel + c];
    switch (joint.channels[c]) {
      case Channel::kXpos: position.x() = value; break;
      case Channel::kYpos: position.y() = value; break;
      case Channel::kZpos: position.z() = value; break;
      default: break;
    }
  }
  return position;
}

}  // namespace

sim::Clip LoadBvhClip(const std::string& path, const ClipImportOptions& options) {
  ValidateClipOptions(path, options);
  Tokens tokens(path, ReadWholeFile(path, "BVH file"));
  BvhFile file;
  ParseHierarchy(tokens, file);
  ParseMotion(tokens, file);

  std::vector<Eigen::Vector3d> joint_points;
  const std::vector<Eigen::Vector3d> points = RestPoints(file, joint_points);
  const UpAxis up = DetectUp(file, joint_points, options.up);
  const Eigen::Matrix3d to_y_up = UpRotation(up);
  double lowest = INFINITY, highest = -INFINITY;
  for (const Eigen::Vector3d& p : points) {
    lowest = std::min(lowest, (to_y_up * p).y());
    highest = std::max(highest, (to_y_up * p).y());
  }
  const double scale = options.scale > 0.0 ? options.scale : GuessMetresPerUnit(highest - lowest);
  // The rest skeleton stands on y = 0 above the origin.
  const Eigen::Vector3d rest_root(0.0, -lowest * scale, 0.0);

  std::vector<sim::Joint> joints(file.joints.size());
  for (std::size_t j = 0; j < joints.size(); ++j) {
    const BvhJoint& source = file.joints[j];
    joints[j].name = source.name;
    joints[j].parent = source.parent;
    joints[j].rest_local.translation() =
        source.parent < 0 ? rest_root : Eigen::Vector3d(scale * (to_y_up * source.offset));
  }
  MapToHAnim(joints);

  sim::Clip clip;
  clip.name = options.name.empty() ? std::filesystem::path(path).stem().string() : options.name;
  clip.category = options.category;
  clip.skeleton = sim::Skeleton::Create(clip.name, std::move(joints));
  clip.frame_time = file.frame_time;
  clip.loops = options.loops.value_or(false);
  clip.provenance = path;
  const Eigen::Quaterniond to_y_up_q(to_y_up);
  clip.frames.resize(file.num_frames);
  const std::vector<Channel>& root_channels = file.joints[0].channels;
  const bool has_position = std::any_of(root_channels.begin(), root_channels.end(), [](Channel c) {
    return c == Channel::kXpos || c == Channel::kYpos || c == Channel::kZpos;
  });
  for (long f = 0; f < file.num_frames; ++f) {
    const double* values = file.values.data() + f * file.num_channels;
    sim::Pose& pose = clip.frames[f];
    pose.rotations.resize(file.joints.size());
    for (std::size_t j = 0; j < file.joints.size(); ++j) {
      pose.rotations[j] = to_y_up_q * FrameRotation(file.joints[j], values) * to_y_up_q.conjugate();
    }
    // The first root's file position is absolute; all roots share Pose::root_translation.
    const BvhJoint& root = file.joints[0];
    pose.root_translation =
        has_position ? Eigen::Vector3d(scale * (to_y_up * FramePosition(root, values)) - rest_root)
                     : Eigen::Vector3d::Zero();
  }
  if (options.start_at_origin) MoveStartToOrigin(clip);
  sim::ValidateClip(clip);
  return clip;
}

}  // namespace costume::assets
