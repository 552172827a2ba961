#include "haptic_server/openhaptics_device.h"

#include <HD/hd.h>

#include <ctime>
#include <type_traits>

namespace costume::haptics {

static_assert(HD_DEVICE_BUTTON_1 == kHdButton1 && HD_DEVICE_BUTTON_2 == kHdButton2,
              "hd_servo_bridge.h's button bits must match hd.h");
static_assert(std::is_same_v<HHD, unsigned int>, "HHD is stored as unsigned int");
static_assert(sizeof(HDSchedulerHandle) <= sizeof(unsigned long), "scheduler handle storage");

namespace {

std::string ErrorText(const HDErrorInfo& error) {
  return std::string(hdGetErrorString(error.errorCode)) + " (HD error " +
         std::to_string(error.errorCode) + ", internal " +
         std::to_string(error.internalErrorCode) + ")";
}

double MonotonicSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

OpenHapticsDevice::OpenHapticsDevice(std::string config_name)
    : config_name_(std::move(config_name)) {}

OpenHapticsDevice::~OpenHapticsDevice() { Close(); }

std::string OpenHapticsDevice::name() const {
  return "OpenHaptics '" + (config_name_.empty() ? std::string("default device") : config_name_) +
         "'" + (model_type_.empty() ? "" : " (" + model_type_ + ")");
}

// hdGetError pops the error stack: each check reads it once and passes it on.
template <typename HdErrorInfo>
DeviceStatus OpenHapticsDevice::Fail(const std::string& what, const HdErrorInfo& error) {
  Close();
  return DeviceStatus::Error(name() + ": " + what + " failed: " + ErrorText(error));
}

DeviceStatus OpenHapticsDevice::Open() {
  if (initialised_) return DeviceStatus::Ok();
  handle_ = hdInitDevice(config_name_.empty() ? HD_DEFAULT_DEVICE : config_name_.c_str());
  if (const HDErrorInfo error = hdGetError();
      HD_DEVICE_ERROR(error) || handle_ == HD_INVALID_HANDLE) {
    return DeviceStatus::Error(name() + ": hdInitDevice failed: " + ErrorText(error) +
                               "; is the device connected and configured in Touch Setup?");
  }
  initialised_ = true;
  hdMakeCurrentDevice(handle_);
  if (const char* type = hdGetString(HD_DEVICE_MODEL_TYPE)) model_type_ = type;
  set_model(DeviceModelFromHdModelType(model_type_));
  HDdouble nominal_force = 0.0, nominal_stiffness = 0.0;
  hdGetDoublev(HD_NOMINAL_MAX_FORCE, &nominal_force);
  hdGetDoublev(HD_NOMINAL_MAX_STIFFNESS, &nominal_stiffness);  // N/mm
  set_limits(MergeReportedLimits(LimitsFor(model()), nominal_force, nominal_stiffness));
  hdEnable(HD_FORCE_OUTPUT);
  if (const HDErrorInfo error = hdGetError(); HD_DEVICE_ERROR(error)) {
    return Fail("hdEnable(HD_FORCE_OUTPUT)", error);
  }

  HdServoBridge::Open();  // before the first callback, so it never sees a closed bridge
  callback_ = hdScheduleAsynchronous(
      [](void* self) -> HDCallbackCode {
        return static_cast<HDCallbackCode>(OpenHapticsDevice::ServoCallback(self));
      },
      this, HD_MAX_SCHEDULER_PRIORITY);
  if (const HDErrorInfo error = hdGetError(); HD_DEVICE_ERROR(error)) {
    return Fail("hdScheduleAsynchronous", error);
  }
  scheduled_ = true;
  hdStartScheduler();
  if (const HDErrorInfo error = hdGetError(); HD_DEVICE_ERROR(error)) {
    return Fail("hdStartScheduler", error);
  }
  return DeviceStatus::Ok();
}

DeviceStatus OpenHapticsDevice::Close() {
  HdServoBridge::Close();  // the servo now sends zero until it stops
  if (!initialised_) return DeviceStatus::Ok();
  hdStopScheduler();
  if (scheduled_) hdUnschedule(callback_);
  scheduled_ = false;
  hdDisableDevice(handle_);
  initialised_ = false;
  const HDErrorInfo error = hdGetError();
  if (HD_DEVICE_ERROR(error)) {
    return DeviceStatus::Error(name() + ": closing reported " + ErrorText(error));
  }
  return DeviceStatus::Ok();
}

unsigned int OpenHapticsDevice::ServoCallback(void* self_pointer) {
  auto* self = static_cast<OpenHapticsDevice*>(self_pointer);
  HdServoSample sample;
  hdBeginFrame(self->handle_);
  sample.time = MonotonicSeconds();
  hdGetDoublev(HD_CURRENT_POSITION, sample.position_mm.data());
  hdGetDoublev(HD_CURRENT_VELOCITY, sample.velocity_mm_s.data());
  hdGetDoublev(HD_CURRENT_TRANSFORM, sample.transform.data());
  HDint buttons = 0;
  hdGetIntegerv(HD_CURRENT_BUTTONS, &buttons);
  sample.buttons = buttons;
  sample.error = HD_DEVICE_ERROR(hdGetError());
  const std::array<double, 3> force = self->ServoExchange(sample);
  hdSetDoublev(HD_CURRENT_FORCE, force.data());
  hdEndFrame(self->handle_);
  // An error here (e.g. HD_EXCEEDED_MAX_FORCE) is reported on the next frame's sample.
  return HD_CALLBACK_CONTINUE;
}

}  // namespace costume::haptics
