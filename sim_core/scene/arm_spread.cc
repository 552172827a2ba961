#include "sim_core/scene/arm_spread.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/surface_geometry.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kSampleRate = 30.0;  // clip frames sampled per second [Hz]
constexpr double kAngleStep = 3.0 * M_PI / 180.0;
/// The steps of kAngleStep that reach kMaxAutoArmSpread.
const int kLastStep = static_cast<int>(std::ceil(kMaxAutoArmSpread / kAngleStep - 1e-9));

/// Per arm (0 left, 1 right) its segments: the upper arm, then the forearm and the hand,
/// whose skin the search keeps off the rest of the body.
constexpr std::array<std::array<HAnimJoint, 3>, 2> kArmSegments = {{
    {HAnimJoint::kLShoulder, HAnimJoint::kLElbow, HAnimJoint::kLRadiocarpal},
    {HAnimJoint::kRShoulder, HAnimJoint::kRElbow, HAnimJoint::kRRadiocarpal},
}};

/// Per arm, the skin vertices of its forearm and hand.
std::array<std::vector<int>, 2> ArmVertices(const Avatar& avatar) {
  std::array<std::vector<int>, 2> arms;
  const std::vector<std::optional<HAnimJoint>>& segments = avatar.vertex_segments();
  for (int v = 0; v < avatar.num_vertices(); ++v) {
    for (int side = 0; side < 2; ++side) {
      if (segments[v] == kArmSegments[side][1] || segments[v] == kArmSegments[side][2]) {
        arms[side].push_back(v);
      }
    }
  }
  return arms;
}

/// Samples a clip on an avatar with a given spread and tells which arm vertices lie within
/// the clearance of the rest of the body.
class NearnessProbe {
 public:
  /// `surface`: the avatar's triangles' topology, for the vertices' normals.
  NearnessProbe(std::shared_ptr<const Avatar> avatar, std::shared_ptr<const Clip> clip,
                AvatarMotionSettings settings, const SurfacePseudonormals& surface)
      : avatar_(std::move(avatar)),
        clip_(std::move(clip)),
        settings_(std::move(settings)),
        surface_(surface) {
    BucketSkin();
  }
  // other_boxes_ points into boxes_.
  NearnessProbe(const NearnessProbe&) = delete;
  NearnessProbe& operator=(const NearnessProbe&) = delete;

  /// Plays the clip with `spread` from now on. Making the motion retargets the clip, so it
  /// is made again only when the spread changes.
  void Spread(const std::array<double, 2>& spread) {
    if (motion_ && settings_.arm_spread == spread) return;
    settings_.arm_spread = spread;
    motion_.emplace(avatar_, clip_, settings_);
  }

  /// Poses the avatar at scene time t; then Near() reads that pose.
  void PoseAt(double t) {
    motion_->Evaluate(t);
    const Points& x = motion_->vertices();
    for (std::size_t s = 0; s < boxes_.size(); ++s) {
      const int joint = s < kNumHAnimJoints ? joints_[s] : -1;
      boxes_[s].to_local = joint >= 0 ? motion_->joint_world()[joint].inverse()
                                      : Eigen::Isometry3d::Identity();
      boxes_[s].world.setEmpty();
      boxes_[s].local.setEmpty();
    }
    for (int v = 0; v < x.rows(); ++v) boxes_[bucket_[v]].Extend(x.row(v).transpose());
    CollectOtherBoxes();
    body_current_ = false;
  }

  /// Whether skin vertex v of arm `side` (0 left, 1 right), pushed kArmClearance out along
  /// its normal, is inside the body. Only a point within the box of another segment's skin
  /// can be: the body's tree is refitted to the pose, and the point's winding counted, for
  /// those alone.
  bool Near(int v, int side) {
    const Points& x = motion_->vertices();
    // The pushed point lies within the clearance of the vertex (the normal is a unit
    // vector): a vertex that far from every other box needs no normal, which is most of
    // them in most frames.
    if (!InOtherBox(x.row(v).transpose(), side, kBoxSlack * kArmClearance)) return false;
    // The normals of the few vertices that get here, from their own triangles: updating
    // every face of the body for them was a tenth of a search.
    const Eigen::Vector3d p =
        x.row(v).transpose() + kArmClearance * surface_.VertexNormalOf(v, x);
    if (!InOtherBox(p, side)) return false;
    if (!body_current_) Body().Update(x);
    body_current_ = true;
    return Body().Inside(p, &rest_pieces_[side]);
  }

 private:
  /// Room for the rounding of a point pushed the clearance along a unit normal [-].
  static constexpr double kBoxSlack = 1.001;

  /// A segment's skin bounded in the world, a cheap first test, and in its joint's frame,
  /// where a limb's box stays tight however the limb is turned (a thigh swung forward has a
  /// world box that holds the hand swinging beside it).
  struct SegmentBox {
    Eigen::AlignedBox3d world, local;
    Eigen::Isometry3d to_local = Eigen::Isometry3d::Identity();

    void Extend(const Eigen::Vector3d& p) {
      world.extend(p);
      local.extend(to_local * p);
    }
    /// Whether `p` lies within `margin` [m] of both boxes.
    bool Holds(const Eigen::Vector3d& p, double margin) const {
      if (margin > 0.0) {
        return world.squaredExteriorDistance(p) <= margin * margin &&
               local.squaredExteriorDistance(to_local * p) <= margin * margin;
      }
      return world.contains(p) && local.contains(to_local * p);
    }
  };

  /// Whether `p` lies within `margin` [m] of the box of a segment's skin other than the
  /// arm's own.
  bool InOtherBox(const Eigen::Vector3d& p, int side, double margin = 0.0) const {
    for (const SegmentBox* box : other_boxes_[side]) {
      if (box->Holds(p, margin)) return true;
    }
    return false;
  }

  /// Per skin vertex its box (its H-Anim segment, kNumHAnimJoints for none), and per
  /// segment its joint.
  void BucketSkin() {
    const std::vector<std::optional<HAnimJoint>>& segments = avatar_->vertex_segments();
    bucket_.resize(segments.size());
    for (std::size_t v = 0; v < segments.size(); ++v) {
      bucket_[v] = segments[v] ? static_cast<int>(*segments[v]) : kNumHAnimJoints;
    }
    for (int s = 0; s < kNumHAnimJoints; ++s) {
      joints_[s] = avatar_->skeleton().Find(static_cast<HAnimJoint>(s));
    }
  }

  /// Per arm, the boxes of the pose's skin other than the arm's own, the empty left out:
  /// InOtherBox runs for every arm vertex of every pose.
  void CollectOtherBoxes() {
    for (int side = 0; side < 2; ++side) {
      other_boxes_[side].clear();
      for (int s = 0; s <= kNumHAnimJoints; ++s) {
        if (!OwnArm(s, side) && !boxes_[s].world.isEmpty()) {
          other_boxes_[side].push_back(&boxes_[s]);
        }
      }
    }
  }

  /// Whether box `bucket` (an H-Anim segment, kNumHAnimJoints for none) is of arm `side`.
  static bool OwnArm(int bucket, int side) {
    if (bucket >= kNumHAnimJoints) return false;
    const std::array<HAnimJoint, 3>& own = kArmSegments[side];
    return std::find(own.begin(), own.end(), static_cast<HAnimJoint>(bucket)) != own.end();
  }

  /// The body's trees, built when a point first passes the boxes: building them is most
  /// of a clean clip's search (78 of 126 ms for the built-in walk on the built-in
  /// humanoid). Throws InputError as MeshDistance does.
  MeshDistance& Body() {
    if (!body_) {
      body_.emplace("avatar '" + avatar_->name() + "'", avatar_->rest_vertices(),
                    avatar_->triangles());
      FindRestPieces();
    }
    return *body_;
  }

  /// Per arm, the body's pieces that hold skin other than the arm's: a body made of
  /// closed pieces (the built-in humanoid's tubes) has pieces of the arm alone, and a point
  /// inside those is inside the arm, not near the rest of the body.
  void FindRestPieces() {
    const std::vector<Eigen::Vector3i>& triangles = avatar_->triangles();
    for (int side = 0; side < 2; ++side) {
      rest_pieces_[side].assign(body_->num_pieces(), 0);
      for (std::size_t t = 0; t < triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
          if (!OwnArm(bucket_[triangles[t][k]], side)) {
            rest_pieces_[side][body_->piece_of(static_cast<int>(t))] = 1;
          }
        }
      }
    }
  }

  std::shared_ptr<const Avatar> avatar_;
  std::shared_ptr<const Clip> clip_;
  AvatarMotionSettings settings_;
  std::optional<MeshDistance> body_;
  bool body_current_ = false;
  const SurfacePseudonormals& surface_;
  std::optional<AvatarMotion> motion_;
  std::vector<int> bucket_;
  std::array<int, kNumHAnimJoints> joints_{};
  std::array<std::vector<char>, 2> rest_pieces_;
  /// Per H-Anim segment the boxes of its skin in the pose; the last for skin of none.
  std::array<SegmentBox, kNumHAnimJoints + 1> boxes_;
  std::array<std::vector<const SegmentBox*>, 2> other_boxes_;
};

/// The search over one clip: per arm and sampled frame, which of the arm's vertices count
/// and whether the arm comes near the body.
class SpreadSearch {
 public:
  SpreadSearch(NearnessProbe& probe, std::vector<double> times,
               std::array<std::vector<int>, 2> arms)
      : probe_(probe), times_(std::move(times)), arms_(std::move(arms)) {
    for (int side = 0; side < 2; ++side) {
      near_[side].assign(times_.size(), 1);
      fixable_[side].assign(times_.size(), std::vector<char>(arms_[side].size(), 1));
    }
  }

  /// Skin the arm's own shape holds near the body, whatever the spread, does not count: a
  /// forearm folded against the upper arm at a bent elbow turns with the whole arm.
  /// Vertices near the body with the arms turned out as far as the search goes are such;
  /// only frames found near so far need the test.
  void DropUnfixable() {
    probe_.Spread({kMaxAutoArmSpread, kMaxAutoArmSpread});
    for (std::size_t i = 0; i < times_.size(); ++i) {
      if (!near_[0][i] && !near_[1][i]) continue;
      probe_.PoseAt(times_[i]);
      for (int side = 0; side < 2; ++side) {
        for (std::size_t k = 0; k < arms_[side].size(); ++k) {
          fixable_[side][i][k] = !probe_.Near(arms_[side][k], side);
        }
      }
    }
  }

  /// Tests, with `spread`, the frames still near, and marks those now clear.
  void MarkNear(const std::array<double, 2>& spread) {
    probe_.Spread(spread);
    for (std::size_t i = 0; i < times_.size(); ++i) {
      if (!near_[0][i] && !near_[1][i]) continue;
      probe_.PoseAt(times_[i]);
      for (int side = 0; side < 2; ++side) {
        if (near_[side][i]) near_[side][i] = ArmNear(side, i);
      }
    }
  }

  /// Per arm, the least number of kAngleStep steps that clears every frame near as
  /// retargeted which some step up to the last clears; `stuck` gets the number of frames
  /// none clears. An arm turned farther from the body does not come nearer it, so a frame
  /// clear with one step is clear with more: each frame is tried from the most steps the
  /// frames before it needed, and most are posed once. (Trying every frame near at each
  /// step in turn posed a frame that needs the last step at all five.)
  std::array<int, 2> LeastClearSteps(std::array<int, 2>& stuck) {
    std::array<int, 2> least{0, 0};
    stuck = {0, 0};
    for (std::size_t i = 0; i < times_.size(); ++i) {
      std::array<int, 2> steps = least;
      std::array<bool, 2> open{};
      for (int side = 0; side < 2; ++side) {
        open[side] = near_[side][i];
        if (open[side]) steps[side] = std::max(steps[side], 1);  // near with none is known
      }
      while (open[0] || open[1]) {
        probe_.Spread({Angle(steps[0]), Angle(steps[1])});
        probe_.PoseAt(times_[i]);
        for (int side = 0; side < 2; ++side) {
          if (!open[side]) continue;
          if (!ArmNear(side, i)) {
            open[side] = false;
            least[side] = std::max(least[side], steps[side]);
          } else if (steps[side] == kLastStep) {
            open[side] = false;
            ++stuck[side];
          } else {
            ++steps[side];
          }
        }
      }
    }
    return least;
  }

  /// The spread of `steps` steps [rad].
  static double Angle(int steps) { return std::min(steps * kAngleStep, kMaxAutoArmSpread); }

  int FramesNear(int side) const {
    return static_cast<int>(std::count(near_[side].begin(), near_[side].end(), 1));
  }

 private:
  bool ArmNear(int side, std::size_t frame) {
    for (std::size_t k = 0; k < arms_[side].size(); ++k) {
      if (fixable_[side][frame][k] && probe_.Near(arms_[side][k], side)) return true;
    }
    return false;
  }

  NearnessProbe& probe_;
  std::vector<double> times_;
  std::array<std::vector<int>, 2> arms_;
  std::array<std::vector<char>, 2> near_;
  std::array<std::vector<std::vector<char>>, 2> fixable_;
};

/// The scene times at which the clip is sampled: after the fit and the blend, over one
/// playing of the clip.
std::vector<double> SampleTimes(const Clip& clip, const AvatarMotionSettings& settings) {
  const double start = settings.fit_time + settings.blend_time;
  const double length = std::max(clip.duration(), clip.frame_time);
  const int count =
      std::clamp(static_cast<int>(std::ceil(length * kSampleRate)), 1, kMaxArmSpreadSamples);
  std::vector<double> times(count);
  for (int i = 0; i < count; ++i) times[i] = start + length * i / count;
  return times;
}

}  // namespace

ArmSpreadFit FindArmSpread(const std::shared_ptr<const Avatar>& avatar,
                           const std::shared_ptr<const Clip>& clip,
                           const AvatarMotionSettings& settings) {
  ArmSpreadFit fit;
  if (!clip) {
    fit.why_not = "no clip";
    return fit;
  }
  SurfacePseudonormals surface(avatar->num_vertices(), avatar->triangles());
  if (surface.num_open_edges() > 0) {
    fit.why_not = "the avatar's mesh is not closed";
    return fit;
  }
  std::array<std::vector<int>, 2> arms = ArmVertices(*avatar);
  try {
    AvatarMotionSettings played = settings;
    played.arm_spread = {0.0, 0.0};
    NearnessProbe probe(avatar, clip, played, surface);
    // Vertices near the body in the posture (a hand resting on a thigh) are the avatar's
    // own shape, which no spread of the clip should be asked to change.
    probe.Spread({0.0, 0.0});
    probe.PoseAt(settings.fit_time);
    for (int side = 0; side < 2; ++side) {
      std::erase_if(arms[side], [&](int v) { return probe.Near(v, side); });
    }
    const std::vector<double> times = SampleTimes(*clip, settings);
    fit.frames_sampled = static_cast<int>(times.size());
    SpreadSearch search(probe, times, std::move(arms));
    search.MarkNear({0.0, 0.0});
    if (search.FramesNear(0) + search.FramesNear(1) > 0) {
      search.DropUnfixable();
      search.MarkNear({0.0, 0.0});  // the frames near, now without that skin
    }
    fit.frames_near_before = {search.FramesNear(0), search.FramesNear(1)};
    // Where no step clears a frame, more steps than the other frames need would not make
    // fewer frames near: the least angle with the fewest.
    const std::array<int, 2> steps = search.LeastClearSteps(fit.frames_near_after);
    fit.angle = {SpreadSearch::Angle(steps[0]), SpreadSearch::Angle(steps[1])};
    fit.measured = true;
  } catch (const InputError& error) {
    fit.why_not = error.what();
    fit.angle = {0.0, 0.0};
  }
  return fit;
}

namespace {

bool SamePose(const Pose& a, const Pose& b) {
  if (a.rotations.size() != b.rotations.size()) return false;
  for (std::size_t j = 0; j < a.rotations.size(); ++j) {
    if (a.rotations[j].coeffs() != b.rotations[j].coeffs()) return false;
  }
  return a.root_translation == b.root_translation &&
         a.orientation.coeffs() == b.orientation.coeffs();
}

/// Whether FindArmSpread would answer `a` as `b`: it ignores their own arm_spread.
bool SameSearch(const AvatarMotionSettings& a, const AvatarMotionSettings& b) {
  return SamePose(a.posture, b.posture) && a.fit_time == b.fit_time &&
         a.blend_time == b.blend_time;
}

}  // namespace

const ArmSpreadFit& ArmSpreadMemo::Find(const std::shared_ptr<const Avatar>& avatar,
                                        const std::shared_ptr<const Clip>& clip,
                                        const AvatarMotionSettings& settings) {
  // A weak pointer that has expired locks to null, so a freed avatar or clip never matches.
  const bool same = has_fit_ && avatar_.lock() == avatar && clip_.lock() == clip &&
                    SameSearch(settings_, settings);
  if (same) return fit_;
  fit_ = FindArmSpread(avatar, clip, settings);
  avatar_ = avatar;
  clip_ = clip;
  settings_ = settings;
  has_fit_ = true;
  ++num_searches_;
  return fit_;
}

AvatarMotionSettings PlayedMotion(const AvatarSpec& spec, ArmSpreadMemo& memo,
                                  ArmSpreadFit& fit) {
  AvatarMotionSettings motion = spec.motion;
  if (spec.auto_arm_spread) {
    fit = memo.Find(spec.avatar, spec.clip, motion);
    motion.arm_spread = fit.angle;
  } else {
    fit = ArmSpreadFit{};
    fit.angle = motion.arm_spread;
    fit.why_not = "as given, not chosen";
  }
  return motion;
}

AvatarSpec WithPosture(const AvatarSpec& spec, const Pose& posture,
                       const ArmSpreadRequest& request) {
  AvatarSpec posed = spec;
  posed.motion.posture = posture;
  if (request.kind == ArmSpreadRequest::Kind::kAuto) posed.auto_arm_spread = true;
  if (request.kind == ArmSpreadRequest::Kind::kGiven) {
    posed.auto_arm_spread = false;
    posed.motion.arm_spread = request.angle;
  }
  return posed;
}

ArmSpreadFit SpreadForPosture(const AvatarSpec& posed, const ArmSpreadRequest& request,
                              const ArmSpreadFit& current, ArmSpreadMemo& memo) {
  if (request.kind == ArmSpreadRequest::Kind::kKeep) return current;
  ArmSpreadFit fit;
  PlayedMotion(posed, memo, fit);
  return fit;
}

std::string DescribeArmSpread(const ArmSpreadFit& fit) {
  const auto degrees = [](double radians) {
    return std::to_string(static_cast<int>(std::lround(radians * 180.0 / M_PI))) + "°";
  };
  const bool spread = fit.angle[0] > 0.0 || fit.angle[1] > 0.0;
  std::string line = spread ? "arms spread " + degrees(fit.angle[0]) + " (left) and " +
                                  degrees(fit.angle[1]) + " (right)"
                            : std::string("arms as retargeted");
  if (!fit.measured) return line + " (" + fit.why_not + ")";
  const auto frames = [](const std::array<int, 2>& n) {
    return std::to_string(n[0]) + " / " + std::to_string(n[1]);
  };
  const std::string clearance =
      std::to_string(static_cast<int>(std::lround(kArmClearance * 1000.0))) + " mm";
  if (!spread && fit.frames_near_before == std::array<int, 2>{0, 0}) {
    return line + ": the forearms and hands stay " + clearance + " off the body in all " +
           std::to_string(fit.frames_sampled) + " sampled frames of the clip";
  }
  return line + ": the left / right forearm or hand came within " + clearance + " of the body in " +
         frames(fit.frames_near_before) + " of " + std::to_string(fit.frames_sampled) +
         " sampled frames as retargeted, " + frames(fit.frames_near_after) +
         (spread ? " with the spread" : " with any spread up to " + degrees(kMaxAutoArmSpread));
}

}  // namespace costume::sim
