#include "sim_core/avatar/procedural_clips.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>

#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

using J = HAnimJoint;
using Eigen::Vector3d;

constexpr double kFramesPerSecond = 60.0;
constexpr double kPi = std::numbers::pi;
constexpr int kLeft = 0;
constexpr int kRight = 1;

/// The joint angles of one instant [degrees], anatomical: each side's angles mean the same
/// motion on both sides (abduction moves a limb away from the midline). Flexion swings the
/// thigh, upper arm and forearm forward, the calf backward; dorsiflexion lifts the toes.
/// The trunk angles are about world axes: pitch about +x (positive bends forward), yaw
/// about +y (positive turns the front towards +x, the avatar's left), roll about +z
/// (positive lifts the left side).
struct BodyAngles {
  std::array<double, 2> hip_flexion{};
  std::array<double, 2> hip_abduction{};
  std::array<double, 2> knee_flexion{};
  std::array<double, 2> ankle_dorsiflexion{};
  std::array<double, 2> shoulder_flexion{};
  std::array<double, 2> shoulder_abduction{};
  std::array<double, 2> elbow_flexion{};
  double pelvis_yaw = 0.0;
  double pelvis_roll = 0.0;
  double spine_pitch = 0.0;
  double spine_yaw = 0.0;
  double spine_roll = 0.0;
  double head_pitch = 0.0;
  double head_yaw = 0.0;
  /// Root offset [m]; its y is added to the offset that keeps the lower foot on the ground.
  Vector3d root = Vector3d::Zero();
};

Eigen::Quaterniond About(const Vector3d& axis, double degrees) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * kPi / 180.0, axis));
}

Eigen::Quaterniond Pitch(double degrees) { return About(Vector3d::UnitX(), degrees); }
Eigen::Quaterniond Yaw(double degrees) { return About(Vector3d::UnitY(), degrees); }
Eigen::Quaterniond Roll(double degrees) { return About(Vector3d::UnitZ(), degrees); }

void SetRotation(const Skeleton& skeleton, J joint, const Eigen::Quaterniond& rotation,
                 Pose& pose) {
  const int index = skeleton.Find(joint);
  if (index >= 0) pose.rotations[index] = rotation;
}

/// The pose of `angles` with no root offset. The rest frames are taken as world-aligned
/// (as in MakeHumanoidSkeleton), so flexion is a rotation about x and abduction about z.
Pose AnglesToPose(const Skeleton& skeleton, const BodyAngles& a) {
  Pose pose = RestPose(skeleton);
  for (int side : {kLeft, kRight}) {
    const bool left = side == kLeft;
    // Mirroring through the x = 0 plane flips yaw and roll; abduction of the left limb is
    // a positive roll.
    const double mirror = left ? 1.0 : -1.0;
    SetRotation(skeleton, left ? J::kLHip : J::kRHip,
                Roll(mirror * a.hip_abduction[side]) * Pitch(-a.hip_flexion[side]), pose);
    SetRotation(skeleton, left ? J::kLKnee : J::kRKnee, Pitch(a.knee_flexion[side]), pose);
    SetRotation(skeleton, left ? J::kLTalocrural : J::kRTalocrural,
                Pitch(-a.ankle_dorsiflexion[side]), pose);
    SetRotation(skeleton, left ? J::kLShoulder : J::kRShoulder,
                Roll(mirror * a.shoulder_abduction[side]) * Pitch(-a.shoulder_flexion[side]), pose);
    SetRotation(skeleton, left ? J::kLElbow : J::kRElbow, Pitch(-a.elbow_flexion[side]), pose);
  }
  SetRotation(skeleton, J::kSacroiliac, Yaw(a.pelvis_yaw) * Roll(a.pelvis_roll), pose);
  SetRotation(skeleton, J::kVl5, Yaw(a.spine_yaw) * Roll(a.spine_roll) * Pitch(a.spine_pitch),
              pose);
  SetRotation(skeleton, J::kSkullbase, Yaw(a.head_yaw) * Pitch(a.head_pitch), pose);
  return pose;
}

/// Heel and toe of each foot in the ankle's rest frame, from the ankle's rest height h:
/// the sole is at −h, the heel h behind the ankle and the toes 2.8 h ahead of it (the
/// built-in humanoid's feet).
std::array<Vector3d, 2> FootPoints(double ankle_height) {
  return {Vector3d(0.0, -ankle_height, -ankle_height),
          Vector3d(0.0, -ankle_height, 2.8 * ankle_height)};
}

/// The vertical root offset [m] that puts the lowest heel or toe on y = 0 in `pose`
/// (rotations only), so standing and walking feet neither sink nor float.
double GroundContactOffset(const Skeleton& skeleton, const Pose& pose,
                           std::vector<Eigen::Isometry3d>& world) {
  ComputeJointWorld(skeleton, pose, world);
  double lowest = 0.0;
  bool any = false;
  for (J ankle : {J::kLTalocrural, J::kRTalocrural}) {
    const int index = skeleton.Find(ankle);
    if (index < 0) continue;
    const double height = skeleton.rest_world()[index].translation().y();
    for (const Vector3d& point : FootPoints(height)) {
      // The foot point's rest offset is world-aligned; express it in the ankle's frame.
      const Vector3d local = skeleton.rest_world()[index].linear().transpose() * point;
      const double y = (world[index] * local).y();
      lowest = any ? std::min(lowest, y) : y;
      any = true;
    }
  }
  return any ? -lowest : 0.0;
}

/// How the root's height follows the feet.
enum class Ground {
  /// Every frame puts the lower foot on the ground (standing, walking, dancing).
  kLowerFootDown,
  /// One offset for all frames, the least that keeps both feet above the ground in every
  /// frame, so the root's own height function shapes the flight (running): following the
  /// lower foot would make the root jump where the feet trade places.
  kLowestOverClip,
};

/// Samples `angles_at(phase)` (phase in [0, 1), one period) at 60 frames per second over
/// `period` seconds, rounded to whole frames so the last frame leads back into the first.
Clip SampleAngles(const std::string& name, ClipCategory category,
                  std::shared_ptr<const Skeleton> skeleton, double period, Ground ground_mode,
                  const std::function<BodyAngles(double)>& angles_at) {
  Clip clip;
  clip.name = name;
  clip.category = category;
  clip.frame_time = 1.0 / kFramesPerSecond;
  clip.loops = true;
  clip.provenance = "procedural (sim_core/avatar/procedural_clips.cc), no external asset";
  const int num_frames = static_cast<int>(std::lround(period * kFramesPerSecond));
  std::vector<Eigen::Isometry3d> world;
  std::vector<double> ground(num_frames);
  double ground_for_all = -1e9;
  for (int f = 0; f < num_frames; ++f) {
    const BodyAngles angles = angles_at(static_cast<double>(f) / num_frames);
    Pose pose = AnglesToPose(*skeleton, angles);
    ground[f] = GroundContactOffset(*skeleton, pose, world);
    ground_for_all = std::max(ground_for_all, ground[f] - angles.root.y());
    pose.root_translation = angles.root;
    clip.frames.push_back(std::move(pose));
  }
  for (int f = 0; f < num_frames; ++f) {
    clip.frames[f].root_translation.y() +=
        ground_mode == Ground::kLowerFootDown ? ground[f] : ground_for_all;
  }
  clip.skeleton = std::move(skeleton);
  return clip;
}

/// Sets both sides of a limb angle from one side's function of the phase angle, the right
/// side half a period later (a gait).
void Gait(std::array<double, 2>& angle, double phi, const std::function<double(double)>& f) {
  angle[kLeft] = f(phi);
  angle[kRight] = f(phi + kPi);
}

BodyAngles Stand(double phase) {
  // One slow breath per period; body sway and small head and arm movements on top.
  const double phi = 2.0 * kPi * phase;
  BodyAngles a;
  a.spine_pitch = 0.8 * std::sin(phi);
  a.head_pitch = -0.5 * std::sin(phi) + 1.5 * std::sin(2.0 * phi);
  a.head_yaw = 3.0 * std::sin(phi + 0.7);
  for (int side : {kLeft, kRight}) {
    a.shoulder_abduction[side] = 1.5 * std::sin(phi);
    a.shoulder_flexion[side] = 2.0 * std::sin(phi + 0.5);
    a.elbow_flexion[side] = 8.0 + 2.0 * std::sin(phi);
    a.knee_flexion[side] = 2.0 + 1.0 * std::sin(2.0 * phi);
    a.hip_flexion[side] = 1.0 + 0.5 * std::sin(2.0 * phi);
    a.ankle_dorsiflexion[side] = a.knee_flexion[side] - a.hip_flexion[side];
  }
  a.root = Vector3d(0.008 * std::sin(phi), 0.0, 0.004 * std::sin(2.0 * phi));
  return a;
}

BodyAngles Walk(double phase) {
  // phi = 0: left leg in mid-swing; pi/2: left heel strike; -pi/2: left toe-off.
  const double phi = 2.0 * kPi * phase;
  BodyAngles a;
  Gait(a.hip_flexion, phi, [](double p) { return 25.0 * std::sin(p); });
  // Knee flexion peaks (60°) early in the swing and is nearly straight at heel strike.
  Gait(a.knee_flexion, phi,
       [](double p) { return 60.0 * std::pow(0.5 * (1.0 + std::cos(p + 0.35)), 3); });
  Gait(a.ankle_dorsiflexion, phi, [](double p) { return 6.0 * std::sin(p + 0.5); });
  // Each arm swings opposite to its leg.
  Gait(a.shoulder_flexion, phi, [](double p) { return -20.0 * std::sin(p); });
  Gait(a.elbow_flexion, phi, [](double p) { return 15.0 - 10.0 * std::sin(p); });
  a.pelvis_yaw = -5.0 * std::sin(phi);
  a.pelvis_roll = -3.0 * std::cos(phi);
  a.spine_yaw = 7.0 * std::sin(phi);
  a.spine_pitch = 3.0;
  a.head_pitch = -3.0;
  a.head_yaw = -2.0 * std::sin(phi);
  a.root = Vector3d(-0.02 * std::cos(phi), 0.0, 0.0);  // weight over the stance foot
  return a;
}

BodyAngles Run(double phase) {
  const double phi = 2.0 * kPi * phase;
  BodyAngles a;
  Gait(a.hip_flexion, phi, [](double p) { return 15.0 + 35.0 * std::sin(p); });
  Gait(a.knee_flexion, phi,
       [](double p) { return 25.0 + 75.0 * std::pow(0.5 * (1.0 + std::cos(p + 0.3)), 2); });
  // Near flat at mid-stance (dorsiflexion ≈ knee − hip there), pointed at toe-off.
  Gait(a.ankle_dorsiflexion, phi, [](double p) { return 10.0 + 8.0 * std::sin(p + 0.5); });
  Gait(a.shoulder_flexion, phi, [](double p) { return -35.0 * std::sin(p); });
  Gait(a.elbow_flexion, phi, [](double p) { return 85.0 - 10.0 * std::sin(p); });
  a.pelvis_yaw = -8.0 * std::sin(phi);
  a.pelvis_roll = -4.0 * std::cos(phi);
  a.spine_yaw = 11.0 * std::sin(phi);
  a.spine_pitch = 8.0;
  a.head_pitch = -7.0;
  // Lowest at mid-stance (phi = 0, pi: a foot under the body), airborne while the legs
  // are spread.
  const double flight = std::sin(phi);
  a.root = Vector3d(-0.015 * std::cos(phi), 0.07 * flight * flight, 0.0);
  return a;
}

/// A key of a key-framed clip: the phase it is reached at and the angles there.
struct Key {
  double phase;
  BodyAngles angles;
};

/// Eased interpolation between keys (zero velocity at each key): the motion starts and
/// stops smoothly, and a list that ends on its first key loops without a jump.
BodyAngles Interpolate(const std::vector<Key>& keys, double phase) {
  std::size_t i = 0;
  while (i + 2 < keys.size() && keys[i + 1].phase <= phase) ++i;
  const Key& k0 = keys[i];
  const Key& k1 = keys[i + 1];
  double t = std::clamp((phase - k0.phase) / (k1.phase - k0.phase), 0.0, 1.0);
  t = t * t * (3.0 - 2.0 * t);
  auto mix = [t](double x, double y) { return x + t * (y - x); };
  auto mix2 = [&](const std::array<double, 2>& x, const std::array<double, 2>& y) {
    return std::array<double, 2>{mix(x[0], y[0]), mix(x[1], y[1])};
  };
  const BodyAngles& a = k0.angles;
  const BodyAngles& b = k1.angles;
  BodyAngles out;
  out.hip_flexion = mix2(a.hip_flexion, b.hip_flexion);
  out.hip_abduction = mix2(a.hip_abduction, b.hip_abduction);
  out.knee_flexion = mix2(a.knee_flexion, b.knee_flexion);
  out.ankle_dorsiflexion = mix2(a.ankle_dorsiflexion, b.ankle_dorsiflexion);
  out.shoulder_flexion = mix2(a.shoulder_flexion, b.shoulder_flexion);
  out.shoulder_abduction = mix2(a.shoulder_abduction, b.shoulder_abduction);
  out.elbow_flexion = mix2(a.elbow_flexion, b.elbow_flexion);
  out.pelvis_yaw = mix(a.pelvis_yaw, b.pelvis_yaw);
  out.pelvis_roll = mix(a.pelvis_roll, b.pelvis_roll);
  out.spine_pitch = mix(a.spine_pitch, b.spine_pitch);
  out.spine_yaw = mix(a.spine_yaw, b.spine_yaw);
  out.spine_roll = mix(a.spine_roll, b.spine_roll);
  out.head_pitch = mix(a.head_pitch, b.head_pitch);
  out.head_yaw = mix(a.head_yaw, b.head_yaw);
  out.root = a.root + t * (b.root - a.root);
  return out;
}

/// Both legs alike (hip, knee, ankle flexion), both arms alike (shoulder flexion, elbow).
BodyAngles Symmetric(double hip, double knee, double ankle, double shoulder, double elbow,
                     double spine, Vector3d root) {
  BodyAngles a;
  a.hip_flexion = {hip, hip};
  a.knee_flexion = {knee, knee};
  a.ankle_dorsiflexion = {ankle, ankle};
  a.shoulder_flexion = {shoulder, shoulder};
  a.elbow_flexion = {elbow, elbow};
  a.spine_pitch = spine;
  a.head_pitch = -0.6 * spine;  // keep looking ahead
  a.root = root;
  return a;
}

BodyAngles Jump(double phase) {
  // Feet flat needs ankle dorsiflexion = knee − hip; less points the toes down. The root's
  // y here is the height of the lowest foot point above the ground.
  static const std::vector<Key> keys = {
      {0.00, Symmetric(0, 0, 0, 0, 10, 0, {0, 0, 0})},
      {0.10, Symmetric(0, 0, 0, 0, 10, 0, {0, 0, 0})},
      {0.30, Symmetric(60, 100, 40, -45, 20, 30, {0, 0, -0.08})},  // crouch, arms back
      {0.42, Symmetric(-5, 5, -25, 160, 20, 0, {0, 0, 0})},        // push off on the toes
      {0.55, Symmetric(10, 30, 0, 150, 20, 0, {0, 0.32, 0})},      // top of the flight
      {0.68, Symmetric(0, 10, -20, 100, 20, 0, {0, 0, 0})},        // touch down, toes first
      {0.80, Symmetric(45, 80, 35, 20, 20, 20, {0, 0, -0.05})},    // absorb the landing
      {0.95, Symmetric(0, 0, 0, 0, 10, 0, {0, 0, 0})},
      {1.00, Symmetric(0, 0, 0, 0, 10, 0, {0, 0, 0})}};
  return Interpolate(keys, phase);
}

/// A kick with the right leg: `hip`, `knee`, `ankle` of the kicking leg; the standing leg
/// slightly bent; the arms counter-swing; the trunk leans back by `lean`.
BodyAngles KickKey(double hip, double knee, double ankle, double support_knee, double arms,
                   double lean) {
  BodyAngles a = Symmetric(0.0, 0.0, 0.0, 0.0, 15.0, -lean, Vector3d::Zero());
  a.hip_flexion[kRight] = hip;
  a.knee_flexion[kRight] = knee;
  a.ankle_dorsiflexion[kRight] = ankle;
  a.knee_flexion[kLeft] = support_knee;
  a.hip_flexion[kLeft] = 0.5 * support_knee;
  a.ankle_dorsiflexion[kLeft] = 0.5 * support_knee;
  a.shoulder_flexion = {arms, -arms};
  a.shoulder_abduction = {std::abs(arms) * 0.6, std::abs(arms) * 0.6};
  a.root = Vector3d(0.03 * support_knee / 12.0, 0.0, 0.0);  // weight over the left foot
  return a;
}

BodyAngles Kick(double phase) {
  static const std::vector<Key> keys = {
      {0.00, KickKey(0, 0, 0, 0, 0, 0)},          {0.12, KickKey(0, 0, 0, 6, 0, 0)},
      {0.28, KickKey(-15, 55, -10, 12, -15, -3)},  // wind up
      {0.42, KickKey(70, 5, -25, 12, 35, 10)},     // the kick
      {0.55, KickKey(55, 45, -15, 12, 25, 6)},     // retract
      {0.72, KickKey(10, 30, 0, 10, 5, 0)},        // put the foot down
      {0.88, KickKey(0, 0, 0, 2, 0, 0)},          {1.00, KickKey(0, 0, 0, 0, 0, 0)}};
  return Interpolate(keys, phase);
}

BodyAngles Dance(double phase) {
  // Eight beats (120 bpm over 4 s): a knee bounce on every beat, a hip sway every two,
  // a torso twist every four; the arms change from pumping forward (start and end) to
  // waving overhead (middle), blended by `overhead`.
  const double phi = 2.0 * kPi * phase;
  const double bounce = 0.5 * (1.0 - std::cos(8.0 * phi));
  const double sway = std::sin(4.0 * phi);
  const double overhead = 0.5 * (1.0 - std::cos(phi));
  BodyAngles a;
  for (int side : {kLeft, kRight}) {
    const double sign = side == kLeft ? 1.0 : -1.0;
    a.knee_flexion[side] = 5.0 + 15.0 * bounce + 5.0 * std::max(0.0, -sign * sway);
    a.hip_flexion[side] = 3.0 + 8.0 * bounce;
    a.ankle_dorsiflexion[side] = a.knee_flexion[side] - a.hip_flexion[side];
    const double pump = 40.0 + 30.0 * sign * std::sin(4.0 * phi);
    const double wave = std::sin(8.0 * phi + sign * 0.5 * kPi);
    a.shoulder_flexion[side] = (1.0 - overhead) * pump + overhead * 10.0;
    a.shoulder_abduction[side] = (1.0 - overhead) * 5.0 + overhead * (120.0 + 15.0 * wave);
    a.elbow_flexion[side] = (1.0 - overhead) * 90.0 + overhead * (35.0 + 25.0 * wave);
  }
  a.pelvis_roll = 6.0 * sway;
  a.spine_roll = -5.0 * sway;
  a.spine_yaw = 15.0 * std::sin(2.0 * phi);
  a.head_yaw = -10.0 * std::sin(2.0 * phi);
  a.head_pitch = 8.0 * bounce - 4.0;
  a.root = Vector3d(0.04 * sway, 0.0, 0.0);
  return a;
}

struct ClipRecipe {
  const char* name;
  ClipCategory category;
  double period;  // [s]
  Ground ground;
  BodyAngles (*angles)(double phase);
};

constexpr ClipRecipe kRecipes[] = {
    {"stand", ClipCategory::kBasic, 4.0, Ground::kLowerFootDown, Stand},
    {"walk", ClipCategory::kBasic, 1.1, Ground::kLowerFootDown, Walk},
    {"run", ClipCategory::kBasic, 0.7, Ground::kLowestOverClip, Run},
    {"jump", ClipCategory::kBasic, 1.6, Ground::kLowerFootDown, Jump},
    {"kick", ClipCategory::kBasic, 1.5, Ground::kLowerFootDown, Kick},
    {"dance", ClipCategory::kChoreography, 4.0, Ground::kLowerFootDown, Dance},
};

}  // namespace

const std::vector<std::string>& BuiltInClipNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> all;
    for (const ClipRecipe& recipe : kRecipes) all.emplace_back(recipe.name);
    return all;
  }();
  return names;
}

Clip MakeBuiltInClip(const std::string& name, std::shared_ptr<const Skeleton> skeleton) {
  if (!skeleton) throw InputError("built-in clip '" + name + "': no skeleton given");
  for (const ClipRecipe& recipe : kRecipes) {
    if (name == recipe.name) {
      return SampleAngles(name, recipe.category, std::move(skeleton), recipe.period, recipe.ground,
                          recipe.angles);
    }
  }
  std::string valid;
  for (const std::string& known : BuiltInClipNames()) {
    valid += (valid.empty() ? "" : ", ") + known;
  }
  throw InputError("built-in clip '" + name + "' is unknown (valid names: " + valid + ")");
}

}  // namespace costume::sim
