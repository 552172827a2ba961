// AvatarMotion against geometry and motion worked out by hand: an arm's spread turns the
// arm about the trunk's forward axis by exactly its angle, and a moving clip blends in
// without a jump in the body's speed.
#include "sim_core/avatar/avatar_motion.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <numbers>

#include "sim_core/common/input_error.h"
#include "tests/support/humanoid.h"

namespace costume::sim {
namespace {

constexpr double kDegree = std::numbers::pi / 180.0;

using test::Humanoid;

/// A clip of the humanoid's own skeleton holding its rest pose.
std::shared_ptr<const Clip> StillClip() {
  auto clip = std::make_shared<Clip>();
  clip->name = "still";
  clip->skeleton = Humanoid()->shared_skeleton();
  clip->frames = {RestPose(*clip->skeleton)};
  return clip;
}

/// Where the joint is once the clip plays, with `settings`.
Eigen::Vector3d JointAt(HAnimJoint joint, const std::shared_ptr<const Clip>& clip,
                        const AvatarMotionSettings& settings, double t = 2.0) {
  AvatarMotion motion(Humanoid(), clip, settings);
  motion.Evaluate(t);
  return motion.joint_world()[Humanoid()->skeleton().Find(joint)].translation();
}

TEST(AvatarMotionArmSpread, TurnsTheArmAboutTheTrunksForwardAxisByItsAngle) {
  // The humanoid faces +z with its left to +x (procedural_humanoid.h): spreading the left
  // arm turns it about +z, its wrist outwards (+x); the right arm stays where it was.
  for (const double heading : {0.0, 90.0}) {
    AvatarMotionSettings plain;
    plain.fit_time = 0.0;
    plain.blend_time = 0.0;
    plain.posture.rotations.assign(Humanoid()->skeleton().num_joints(),
                                   Eigen::Quaterniond::Identity());
    plain.posture.orientation = PostureRotation({0.0, heading, 0.0});
    AvatarMotionSettings spread = plain;
    spread.arm_spread = {12.0 * kDegree, 0.0};
    const Eigen::Vector3d shoulder = JointAt(HAnimJoint::kLShoulder, StillClip(), plain);
    const Eigen::Vector3d u0 = JointAt(HAnimJoint::kLRadiocarpal, StillClip(), plain) - shoulder;
    const Eigen::Vector3d u1 = JointAt(HAnimJoint::kLRadiocarpal, StillClip(), spread) - shoulder;
    EXPECT_NEAR(std::acos(u0.normalized().dot(u1.normalized())), 12.0 * kDegree, 1e-9);
    // The trunk's forward axis, turned with the body.
    const Eigen::Vector3d forward = plain.posture.orientation * Eigen::Vector3d::UnitZ();
    EXPECT_GT(u0.cross(u1).normalized().dot(forward), 1.0 - 1e-9) << "heading " << heading;
    const Eigen::Vector3d left = plain.posture.orientation * Eigen::Vector3d::UnitX();
    // The wrist of an arm half a metre long, hanging 20° from the body, goes from 20° to 32°
    // out: L (sin 32° − sin 20°), about 9 cm.
    EXPECT_GT(u1.dot(left), u0.dot(left) + 0.05);
    EXPECT_LT((JointAt(HAnimJoint::kRRadiocarpal, StillClip(), spread) -
               JointAt(HAnimJoint::kRRadiocarpal, StillClip(), plain))
                  .norm(),
              1e-12);
  }
}

TEST(AvatarMotionArmSpread, RefusesAnAngleOutsideZeroToThirtyDegrees) {
  for (const double angle :
       {-1.0 * kDegree, 31.0 * kDegree, std::numeric_limits<double>::quiet_NaN()}) {
    AvatarMotionSettings settings;
    settings.arm_spread = {0.0, angle};
    try {
      AvatarMotion motion(Humanoid(), StillClip(), settings);
      ADD_FAILURE() << "accepted " << angle;
    } catch (const InputError& error) {
      EXPECT_NE(std::string(error.what()).find("arm spread (right)"), std::string::npos);
      EXPECT_NE(std::string(error.what()).find("30°"), std::string::npos);
    }
  }
}

// The designer sets the spread with a posture: over the transition the wrist moves from the
// old spread's place to the new one's, and once it is over the body is where a motion made
// with the new spread puts it; a spread out of range changes nothing.
TEST(AvatarMotionArmSpread, ASpreadSetWithAPostureIsReachedOverItsTransition) {
  AvatarMotionSettings plain;
  plain.fit_time = 0.0;
  plain.blend_time = 0.0;
  plain.posture = RestPose(Humanoid()->skeleton());
  AvatarMotionSettings spread = plain;
  spread.arm_spread = {12.0 * kDegree, 6.0 * kDegree};
  AvatarMotion motion(Humanoid(), StillClip(), plain);
  motion.Evaluate(2.0);
  EXPECT_THROW(motion.SetPosture(plain.posture, {31.0 * kDegree, 0.0}), InputError);
  EXPECT_EQ(motion.settings().arm_spread, plain.arm_spread);
  const int wrist = Humanoid()->skeleton().Find(HAnimJoint::kLRadiocarpal);
  const Eigen::Vector3d before = motion.joint_world()[wrist].translation();
  motion.SetPosture(plain.posture, spread.arm_spread);
  motion.Evaluate(2.0, 0.0);  // the transition's start: still the pose before
  EXPECT_LT((motion.joint_world()[wrist].translation() - before).norm(), 1e-12);
  motion.Evaluate(2.0, 1.0);
  const Eigen::Vector3d after = JointAt(HAnimJoint::kLRadiocarpal, StillClip(), spread);
  EXPECT_LT((motion.joint_world()[wrist].translation() - after).norm(), 1e-12);
  EXPECT_GT((after - before).norm(), 0.05);  // 12° at the end of an arm half a metre long
}

TEST(AvatarMotionBlend, TheBodyReachesAMovingClipsSpeedWithoutAJump) {
  // A clip walking at 1 m/s along +z blends in over 0.3 s from the standing posture. Blended
  // at the clip's own pace with a weight linear in time, the hips would move at
  // d/dt (t/T · v t) = 2 v t / T: 2 m/s at the blend's end, then 1 m/s at once.
  auto clip = std::make_shared<Clip>();
  clip->name = "glide";
  clip->skeleton = Humanoid()->shared_skeleton();
  clip->frame_time = 2.0;
  clip->loops = false;
  clip->frames = {RestPose(*clip->skeleton), RestPose(*clip->skeleton)};
  clip->frames[1].root_translation = Eigen::Vector3d(0.0, 0.0, 2.0);
  AvatarMotionSettings settings;
  settings.fit_time = 0.5;
  settings.blend_time = 0.3;
  AvatarMotion motion(Humanoid(), clip, settings);
  const double dt = 1e-3;
  const auto hips = [&](double t) {
    motion.Evaluate(t);
    return Eigen::Vector3d(motion.joint_world()[0].translation());
  };
  double fastest = 0.0, sharpest = 0.0, previous_speed = 0.0;
  for (double t = 0.5; t < 1.5; t += dt) {  // the clip's first second
    const double speed = (hips(t + dt) - hips(t)).norm() / dt;
    fastest = std::max(fastest, speed);
    sharpest = std::max(sharpest, std::abs(speed - previous_speed) / dt);
    previous_speed = speed;
  }
  // The clock τ = T (6s³ − 8s⁴ + 3s⁵) runs at most 1.51 times the clip's pace, and the
  // hips accelerate at most 3.94 v / T = 13.1 m/s².
  EXPECT_LT(fastest, 1.55);   // m/s
  EXPECT_LT(sharpest, 14.0);  // m/s²: no step in speed (1 m/s in a millisecond is 1,000)
  EXPECT_NEAR((hips(1.2 + dt) - hips(1.2)).norm() / dt, 1.0, 1e-6);  // the clip's own pace
}

}  // namespace
}  // namespace costume::sim
