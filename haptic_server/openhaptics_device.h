#pragma once
/// @file
/// A Phantom / Touch device through the OpenHaptics HD API. Compiled only when CMake finds the
/// SDK (option COSTUME_WITH_OPENHAPTICS; HD/hd.h and libHD). The SDK's servo thread calls our
/// callback at 1 kHz; all conversion and the hand-over to the tick are in HdServoBridge
/// (hd_servo_bridge.h), which is tested without the SDK. Written against the vendor's
/// documented HD API: hdInitDevice, hdEnable(HD_FORCE_OUTPUT), hdScheduleAsynchronous,
/// hdStartScheduler, and in the callback hdBeginFrame, hdGetDoublev(HD_CURRENT_POSITION [mm],
/// HD_CURRENT_VELOCITY [mm/s], HD_CURRENT_TRANSFORM), hdGetIntegerv(HD_CURRENT_BUTTONS),
/// hdSetDoublev(HD_CURRENT_FORCE [N]), hdEndFrame, hdGetError.

#include <string>

#include "haptic_server/hd_servo_bridge.h"

namespace costume::haptics {

/// One HD device. Open/Close must not run concurrently with each other.
class OpenHapticsDevice final : public HdServoBridge {
 public:
  /// `config_name`: the device name from Touch Setup; empty for HD_DEFAULT_DEVICE.
  explicit OpenHapticsDevice(std::string config_name = "");
  ~OpenHapticsDevice() override;

  std::string name() const override;
  /// Initialises the device, reads its model and nominal limits (the stricter of those and our
  /// table apply), enables force output, schedules the servo callback and starts the scheduler.
  /// On failure returns the HD error text and codes and leaves the device closed.
  DeviceStatus Open() override;
  /// Stops the scheduler, unschedules the callback and disables the device (zero force).
  DeviceStatus Close() override;

 private:
  static unsigned int ServoCallback(void* self);  // HDCallbackCode HDCALLBACK (void*)
  /// Closes and returns the error of `what` (error: an HDErrorInfo, opaque here).
  template <typename HdErrorInfo>
  DeviceStatus Fail(const std::string& what, const HdErrorInfo& error);

  std::string config_name_;
  std::string model_type_;
  unsigned int handle_ = 0;            // HHD
  unsigned long callback_ = 0;         // HDSchedulerHandle
  bool initialised_ = false;
  bool scheduled_ = false;
};

}  // namespace costume::haptics
