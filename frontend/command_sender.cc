#include "frontend/command_sender.h"

#include <cmath>

#include "bus/channels.h"
#include "bus/receive_filter.h"
#include "bus/settings_codec.h"

namespace costume::frontend {
namespace {

using Command = costume_lcm::command;

/// A command of `kind` with every other field zero, except grab_id (-1: "no grab", the
/// value ELIMINATE_STRETCH reads as "use the sphere").
Command Blank(std::int8_t kind) {
  Command message{};
  message.kind = kind;
  message.grab_id = -1;
  message.num_joints = 0;
  return message;
}

}  // namespace

CommandSender::CommandSender(bus::MessageBus& bus, bus::ResendPolicy resend)
    : commands_(bus, bus::kCommandChannel, resend), pointer_(bus, bus::kPointerChannel) {}

bool CommandSender::Send(Command& message) {
  message.utime = bus::NowUtime();
  return commands_.Send(message, message.utime);
}

std::vector<std::string> CommandSender::ResendDue() {
  std::vector<std::string> lines;
  if (commands_.ResendDue(bus::NowUtime()) == 0) return lines;
  for (const Command& c : commands_.given_up()) {
    lines.push_back("warning: command kind " + std::to_string(c.kind) + " (seq " +
                    std::to_string(c.seq) + ") not acknowledged by the simulation server "
                    "after resending; given up");
  }
  return lines;
}

bool CommandSender::SetSelectionRadius(double radius) {
  Command message = Blank(Command::KIND_SET_SELECTION_RADIUS);
  message.radius = radius;
  return Send(message);
}

bool CommandSender::Load(EntryKind kind, std::int64_t database_id, const std::string& name) {
  static constexpr std::int8_t kKinds[] = {Command::KIND_LOAD_AVATAR, Command::KIND_LOAD_COSTUME,
                                           Command::KIND_LOAD_ANIMATION};
  Command message = Blank(kKinds[static_cast<int>(kind)]);
  message.database_id = database_id > 0 ? database_id : 0;
  message.name = name;
  return Send(message);
}

bool CommandSender::SetMode(bool editing) {
  Command message = Blank(Command::KIND_SET_MODE);
  message.mode = editing ? Command::MODE_EDITING : Command::MODE_ANIMATION;
  return Send(message);
}

bool CommandSender::Play() {
  Command message = Blank(Command::KIND_PLAY);
  return Send(message);
}

bool CommandSender::Pause() {
  Command message = Blank(Command::KIND_PAUSE);
  return Send(message);
}

bool CommandSender::Stop() {
  Command message = Blank(Command::KIND_STOP);
  return Send(message);
}

bool CommandSender::SetMaterial(int garment, const sim::Material& material) {
  Command message = Blank(Command::KIND_SET_MATERIAL);
  message.garment = garment;
  message.material = bus::ToMessage(material);
  return Send(message);
}

bool CommandSender::SetSolver(const sim::SolverSettings& settings) {
  Command message = Blank(Command::KIND_SET_SOLVER);
  message.solver = bus::ToMessage(settings);
  return Send(message);
}

bool CommandSender::SetCollision(const sim::CollisionSettings& settings) {
  Command message = Blank(Command::KIND_SET_COLLISION);
  message.collision = bus::ToMessage(settings);
  return Send(message);
}

bool CommandSender::EliminateStretch(const Eigen::Vector3d& centre, double radius) {
  Command message = Blank(Command::KIND_ELIMINATE_STRETCH);
  for (int i = 0; i < 3; ++i) message.centre[i] = centre[i];
  message.radius = radius;
  return Send(message);
}

bool CommandSender::Undo() {
  Command message = Blank(Command::KIND_UNDO);
  return Send(message);
}

bool CommandSender::Redo() {
  Command message = Blank(Command::KIND_REDO);
  return Send(message);
}

bool CommandSender::SaveVersion(const std::string& label) {
  Command message = Blank(Command::KIND_SAVE_VERSION);
  message.name = label;
  return Send(message);
}

bool CommandSender::SetPosture(const std::vector<JointAngles>& joints, double heading_degrees,
                               const sim::ArmSpreadRequest& arm_spread) {
  Command message = Blank(Command::KIND_SET_POSTURE);
  message.num_joints = static_cast<std::int16_t>(joints.size());
  for (const JointAngles& joint : joints) {
    message.joint_names.push_back(joint.joint);
    message.joint_angles.push_back({joint.degrees.x(), joint.degrees.y(), joint.degrees.z()});
  }
  message.heading_degrees = heading_degrees;
  using Kind = sim::ArmSpreadRequest::Kind;
  message.arm_spread_mode = arm_spread.kind == Kind::kAuto    ? Command::ARM_SPREAD_AUTO
                            : arm_spread.kind == Kind::kGiven ? Command::ARM_SPREAD_GIVEN
                                                              : Command::ARM_SPREAD_KEEP;
  for (int side = 0; side < 2; ++side) {
    message.arm_spread_degrees[side] =
        arm_spread.kind == Kind::kGiven ? arm_spread.angle[side] * 180.0 / M_PI : 0.0;
  }
  return Send(message);
}

bool CommandSender::Pointer(const Eigen::Vector3d& position, std::int32_t buttons,
                            bool inside_view) {
  costume_lcm::pointer_sample sample{};
  sample.utime = bus::NowUtime();
  for (int i = 0; i < 3; ++i) sample.position[i] = position[i];
  sample.buttons = buttons;
  sample.inside_view = inside_view;
  return pointer_.Publish(sample);
}

}  // namespace costume::frontend
