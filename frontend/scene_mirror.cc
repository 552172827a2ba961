#include "frontend/scene_mirror.h"

#include <algorithm>
#include <cmath>

#include "assets/scene_file.h"
#include "sim_core/avatar/hanim.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"

namespace costume::frontend {
namespace {

template <class Triangles>
std::vector<std::uint32_t> Flatten(const Triangles& triangles) {
  std::vector<std::uint32_t> indices;
  indices.reserve(3 * triangles.size());
  for (const Eigen::Vector3i& t : triangles) {
    for (int k = 0; k < 3; ++k) indices.push_back(static_cast<std::uint32_t>(t[k]));
  }
  return indices;
}

template <class Points>
std::vector<Eigen::Vector3f> ToFloat(const Points& points) {
  std::vector<Eigen::Vector3f> out(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    out[static_cast<std::size_t>(i)] = points.row(i).transpose().template cast<float>();
  }
  return out;
}

/// The lowest skin point once the fit has moved the avatar into its posture and position.
/// Fixed there: a floor following the feet would rise with every jump of the clip.
float FloorUnder(const sim::AvatarSpec& spec) {
  sim::AvatarMotion fitted(spec.avatar, nullptr, spec.motion);
  fitted.Evaluate(spec.motion.fit_time);
  return static_cast<float>(fitted.vertices().col(1).minCoeff());
}

}  // namespace

sim::SceneDescription LoadScene(const std::string& builtin, const std::string& file) {
  return file.empty() ? assets::LoadBuiltInScene(builtin) : assets::LoadSceneFile(file);
}

SceneMirror::SceneMirror(sim::SceneDescription scene) : scene_(std::move(scene)) {
  sim::ValidateScene(scene_);
  std::vector<sim::GarmentRange> garments;
  std::vector<sim::BodyAttachment> attachments;
  const auto model = sim::BuildSceneModel(scene_, &garments, &attachments);
  num_particles_ = model->num_particles();
  cloth_indices_ = Flatten(model->triangles());
  rest_positions_ = ToFloat(model->rest_positions());
  if (scene_.avatar) {
    const sim::AvatarSpec& spec = *scene_.avatar;
    MakeMotion();
    avatar_indices_ = Flatten(spec.avatar->triangles());
    PoseAvatar();
    floor_height_ = FloorUnder(spec);
  }
}

void SceneMirror::MakeMotion() {
  const sim::AvatarSpec& spec = *scene_.avatar;
  motion_ = std::make_unique<sim::AvatarMotion>(
      spec.avatar, spec.clip, sim::PlayedMotion(spec, arm_spreads_, arm_spread_));
  posture_blending_ = false;
}

void SceneMirror::PoseAvatar() {
  if (!motion_) return;
  // The server moves the body to a new posture over kPostureTransition of simulated time.
  double blend = 1.0;
  if (posture_blending_) {
    blend = std::clamp((last_sim_time_ - posture_start_) / kPostureTransition, 0.0, 1.0);
    if (blend >= 1.0) posture_blending_ = false;
  }
  motion_->Evaluate(avatar_time_, blend);
  avatar_vertices_ = ToFloat(motion_->vertices());
}

void SceneMirror::Follow(const ClothFrame& frame) {
  // A lower frame number is a rebuilt scene (STOP, SET_SOLVER): the clock starts again.
  if (!has_frame_ || frame.frame < last_frame_) {
    // The server built its simulation anew, the posture last set included: its avatar
    // starts again from the rest pose, and its arms' spread is chosen for that posture.
    if (has_frame_ && motion_) MakeMotion();
    avatar_time_ = frame.editing ? 0.0 : frame.sim_time;
  } else if (!frame.editing) {
    avatar_time_ += frame.sim_time - last_sim_time_;
  }
  has_frame_ = true;
  last_frame_ = frame.frame;
  last_sim_time_ = frame.sim_time;
  PoseAvatar();
}

std::vector<std::string> SceneMirror::SetPosture(const std::vector<JointAngles>& joints,
                                                 double heading_degrees,
                                                 const sim::ArmSpreadRequest& arm_spread) {
  std::vector<std::string> unknown;
  if (!motion_ || !scene_.avatar) return unknown;
  // As the server's SET_POSTURE: the listed joints rotated, every other joint at rest, the
  // avatar turned about +y and left where it stands.
  const sim::Skeleton& skeleton = motion_->avatar().skeleton();
  sim::Pose posture;
  posture.rotations.assign(skeleton.num_joints(), Eigen::Quaterniond::Identity());
  posture.root_translation = motion_->settings().posture.root_translation;
  for (const JointAngles& joint : joints) {
    const std::optional<sim::HAnimJoint> hanim = sim::ParseHAnimName(joint.joint);
    const int index = hanim ? skeleton.Find(*hanim) : -1;
    if (index < 0 || !joint.degrees.allFinite()) {
      unknown.push_back(joint.joint);
      continue;
    }
    posture.rotations[index] = sim::PostureRotation(joint.degrees);
  }
  posture.orientation = sim::PostureRotation({0.0, heading_degrees, 0.0});
  sim::AvatarSpec posed = sim::WithPosture(*scene_.avatar, posture, arm_spread);
  sim::ArmSpreadFit fit = sim::SpreadForPosture(posed, arm_spread, arm_spread_, arm_spreads_);
  try {
    motion_->SetPosture(posture, fit.angle);
  } catch (const sim::InputError&) {
    return unknown;  // the server refuses it too (a spread out of range): nothing changes
  }
  *scene_.avatar = std::move(posed);  // as the server's scene: a rebuild keeps it
  arm_spread_ = std::move(fit);
  posture_start_ = last_sim_time_;
  posture_blending_ = true;
  PoseAvatar();
  return unknown;
}

Eigen::AlignedBox3d SceneMirror::Bounds() const {
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3f& p : rest_positions_) box.extend(p.cast<double>());
  for (const Eigen::Vector3f& p : avatar_vertices_) box.extend(p.cast<double>());
  if (box.isEmpty()) box.extend(Eigen::Vector3d::Zero());
  return box;
}

}  // namespace costume::frontend
