#pragma once
/// @file
/// The GUI's local copy of the scene the simulation server runs. cloth_frame carries particle
/// positions only; the triangles that join them and the avatar come from building the same
/// sim::SceneDescription here (the GUI starts the server with the same --builtin/--scene):
/// the garment model gives the triangles, sim::AvatarMotion poses the avatar at the frame's
/// avatar time. The avatar's clock is reconstructed from the frames: it advances with
/// sim_time in mode A and stands still in mode B (the server freezes it, docs/processes.md).
/// The avatar plays the motion the server plays (sim::PlayedMotion: the arms' spread the
/// clip needs included), chosen again when the server rebuilds its scene.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "frontend/cloth_frame_assembler.h"
#include "frontend/command_sender.h"
#include "sim_core/avatar/avatar_motion.h"
#include "sim_core/scene/arm_spread.h"
#include "sim_core/scene/scene_description.h"

namespace costume::frontend {

/// Loads a built-in scene ("garment", "hang", "drape", "demo") or, when `file` is not empty,
/// a scene file. Throws sim::InputError as the loaders do.
sim::SceneDescription LoadScene(const std::string& builtin, const std::string& file);

/// The scene's cloth triangles and avatar, posed along with the received frames.
class SceneMirror {
 public:
  /// Builds the garment model (fitting pattern garments to the avatar) and the avatar's
  /// motion. Throws sim::InputError for a scene the simulation would refuse.
  explicit SceneMirror(sim::SceneDescription scene);

  const sim::SceneDescription& scene() const { return scene_; }
  /// Particles of the merged garments (a frame with another count is not this scene).
  int num_particles() const { return num_particles_; }
  /// Cloth triangles, 3 indices into a frame's positions each.
  const std::vector<std::uint32_t>& cloth_indices() const { return cloth_indices_; }
  /// The cloth as built (before the first frame arrives) [m].
  const std::vector<Eigen::Vector3f>& rest_positions() const { return rest_positions_; }

  /// Advances the avatar's clock to `frame` and poses the avatar there. A frame numbered
  /// below the last is a rebuilt scene: the avatar's motion is made again from the scene,
  /// in the posture last set, as the server's.
  void Follow(const ClothFrame& frame);
  /// The avatar's clock after the last Follow [s].
  double avatar_time() const { return avatar_time_; }

  bool has_avatar() const { return motion_ != nullptr; }
  /// The arms' spread the avatar plays its clip with, as the server chooses it.
  const sim::ArmSpreadFit& arm_spread() const { return arm_spread_; }
  /// The skinned avatar at avatar_time() [m]; empty without an avatar.
  const std::vector<Eigen::Vector3f>& avatar_vertices() const { return avatar_vertices_; }
  const std::vector<std::uint32_t>& avatar_indices() const { return avatar_indices_; }

  /// Applies a posture as the server's KIND_SET_POSTURE does: the listed joints' rotations,
  /// every other joint at rest (unknown names ignored and returned), the heading about +y
  /// [degrees]; the body moves there over kPostureTransition of the frames' simulated time.
  /// The arms' spread changes as `arm_spread` asks, as the server's does.
  std::vector<std::string> SetPosture(const std::vector<JointAngles>& joints,
                                      double heading_degrees,
                                      const sim::ArmSpreadRequest& arm_spread = {});

  /// Applies solver or collision settings to the scene as the server's KIND_SET_SOLVER and
  /// KIND_SET_COLLISION do (in place; without an avatar only self_collision counts), so a
  /// scene loaded on top of this one carries them, as the server's does.
  void SetSolver(const sim::SolverSettings& solver) { scene_.solver = solver; }
  void SetCollision(const sim::CollisionSettings& collision) {
    sim::ApplyCollisionSettings(collision, scene_);
  }

  /// Box around the avatar's rest pose and the cloth as built [m].
  Eigen::AlignedBox3d Bounds() const;
  /// Where the view's floor goes [m]: under the avatar's feet in its fitting posture and
  /// position (MakeHuman's base.obj puts its origin at the hips, the feet at −0.8 m); 0
  /// without an avatar.
  float floor_height() const { return floor_height_; }

 private:
  /// A fresh motion of the scene's avatar, as the server's simulation builds it.
  void MakeMotion();
  void PoseAvatar();

  sim::SceneDescription scene_;
  int num_particles_ = 0;
  std::vector<std::uint32_t> cloth_indices_;
  std::vector<Eigen::Vector3f> rest_positions_;
  sim::ArmSpreadMemo arm_spreads_;
  sim::ArmSpreadFit arm_spread_;
  std::unique_ptr<sim::AvatarMotion> motion_;
  std::vector<Eigen::Vector3f> avatar_vertices_;
  std::vector<std::uint32_t> avatar_indices_;
  float floor_height_ = 0.0f;
  /// The server's posture transition (SimServerOptions::posture_transition) [s].
  static constexpr double kPostureTransition = 0.5;
  double posture_start_ = 0.0;
  bool posture_blending_ = false;
  bool has_frame_ = false;
  std::int64_t last_frame_ = -1;
  double last_sim_time_ = 0.0;
  double avatar_time_ = 0.0;
};

}  // namespace costume::frontend
