#pragma once
/// @file
/// Everything the GUI sends: commands to the simulation server on COSTUME_COMMAND
/// (lcm_types/command.lcm) and the mouse as a haptic device on COSTUME_POINTER
/// (lcm_types/pointer_sample.lcm). One method per command, filling exactly the fields its
/// kind reads and leaving the others zero. Call from the GUI thread only (the publishers
/// number their messages). Commands are resent until a cloth_frame acknowledges them
/// (bus/command_resender.h): the window feeds Acknowledge from its frames and calls ResendDue
/// every ResendPolicy::period_us.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "bus/command_resender.h"
#include "bus/message_bus.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/command.hpp"
#include "lcm_types/costume_lcm/pointer_sample.hpp"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/arm_spread.h"
#include "sim_core/scene/scene_description.h"

namespace costume::frontend {

/// What the lists load (command KIND_LOAD_AVATAR / _COSTUME / _ANIMATION).
enum class EntryKind { kAvatar, kCostume, kAnimation };

/// One joint's rotation of the avatar's posture: about the joint's rest x, y, z axes, in
/// that order [degrees], as [avatar.posture] in scene files.
struct JointAngles {
  std::string joint;  ///< H-Anim joint name, e.g. "l_shoulder"
  Eigen::Vector3d degrees = Eigen::Vector3d::Zero();
};

/// Publishes the GUI's commands and pointer samples on `bus`.
class CommandSender {
 public:
  /// `bus` must outlive the sender. Throws InputError for an invalid `resend` policy.
  explicit CommandSender(bus::MessageBus& bus, bus::ResendPolicy resend = {});

  /// LOAD_*: by database id (> 0), else by name. False when the bus refused the message.
  bool Load(EntryKind kind, std::int64_t database_id, const std::string& name);
  /// SET_MODE: `editing` false = MODE_ANIMATION (mode A), true = MODE_EDITING (mode B).
  bool SetMode(bool editing);
  /// PLAY: frames advance. PAUSE: they stop (still published). STOP: the server rebuilds the
  /// scene at frame 0 and stays stopped.
  bool Play();
  bool Pause();
  bool Stop();
  /// SET_MATERIAL for garment `garment` (-1 = every garment).
  bool SetMaterial(int garment, const sim::Material& material);
  /// SET_SOLVER with every field of `settings` (the server changes it in place).
  bool SetSolver(const sim::SolverSettings& settings);
  /// SET_COLLISION with every field of `settings` (the server changes them in place).
  bool SetCollision(const sim::CollisionSettings& settings);
  /// ELIMINATE_STRETCH over the sphere (`centre` [m], `radius` [m] > 0), grab_id = -1.
  bool EliminateStretch(const Eigen::Vector3d& centre, double radius);
  /// UNDO / REDO of the last stretch elimination (rest lengths).
  bool Undo();
  bool Redo();
  /// SAVE_VERSION with `label` as the version's label.
  bool SaveVersion(const std::string& label);
  /// SET_POSTURE: the listed joints' rotations and the avatar's heading about +y [degrees],
  /// and the arms' spread as `arm_spread` asks (kKeep: unchanged).
  bool SetPosture(const std::vector<JointAngles>& joints, double heading_degrees,
                  const sim::ArmSpreadRequest& arm_spread = {});
  /// SET_SELECTION_RADIUS: the haptic server's grab sphere [m] from its next grab.
  bool SetSelectionRadius(double radius);

  /// A cloth_frame's command_seq: the commands up to it were taken in; no more resends.
  void Acknowledge(std::int64_t command_seq) { commands_.Acknowledge(command_seq); }
  /// Resends the unacknowledged commands that are due; returns one line per command given
  /// up (for the message log).
  std::vector<std::string> ResendDue();
  /// Resends and acknowledgements so far.
  const bus::ResendCounts& resend_counts() const { return commands_.counts(); }

  /// A pointer sample: `position` [m] in the scene frame, `buttons` bit 0 grab, bit 1
  /// eliminate stretch; `inside_view` false when the pointer left the view.
  bool Pointer(const Eigen::Vector3d& position, std::int32_t buttons, bool inside_view);

  /// Commands published so far (the next command's seq).
  std::int64_t commands_sent() const { return commands_.next_seq(); }

 private:
  bool Send(costume_lcm::command& message);

  bus::CommandResender commands_;
  bus::Publisher<costume_lcm::pointer_sample> pointer_;
};

}  // namespace costume::frontend
