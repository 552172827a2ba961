#pragma once
/// @file
/// The LCM channels of the processes and the message type on each (lcm_types/README.md).
/// One sender per channel: `seq` is numbered per channel and the receive filter drops a
/// message whose seq does not increase (receive_filter.h).

#include <string>

namespace costume::bus {

/// costume_lcm::device_state, from haptic_server.
inline const std::string kDeviceStateChannel = "COSTUME_DEVICE_STATE";
/// costume_lcm::grab, from haptic_server.
inline const std::string kGrabChannel = "COSTUME_GRAB";
/// costume_lcm::grab_ack, from the simulation server: each grab echoed on receipt.
inline const std::string kGrabAckChannel = "COSTUME_GRAB_ACK";
/// costume_lcm::feedback, from haptic_server.
inline const std::string kFeedbackChannel = "COSTUME_FEEDBACK";
/// costume_lcm::cloth_frame (chunked), from the simulation server.
inline const std::string kClothFrameChannel = "COSTUME_CLOTH_FRAME";
/// costume_lcm::haptic_patch (chunked), from the simulation server.
inline const std::string kHapticPatchChannel = "COSTUME_HAPTIC_PATCH";
/// costume_lcm::command, from the GUI.
inline const std::string kCommandChannel = "COSTUME_COMMAND";
/// costume_lcm::command, from haptic_server (device buttons, e.g. eliminate stretch).
inline const std::string kHapticCommandChannel = "COSTUME_COMMAND_HAPTIC";
/// costume_lcm::pointer_sample, from the GUI (the mouse as a haptic device).
inline const std::string kPointerChannel = "COSTUME_POINTER";
/// costume_lcm::status, one channel per process.
inline const std::string kSimStatusChannel = "COSTUME_STATUS_SIM";
inline const std::string kHapticStatusChannel = "COSTUME_STATUS_HAPTIC";
inline const std::string kFrontendStatusChannel = "COSTUME_STATUS_FRONTEND";

}  // namespace costume::bus
