#pragma once
/// @file
/// The haptic device interface (STYLE.md §4): every device the haptic server drives — the
/// OpenHaptics HD API (Touch, Omni, Desktop), CyberGrasp, the simulated device, the GUI's mouse
/// and log playback — sits behind HapticDevice, so the 1 kHz tick and its tests never know
/// which one they talk to.
///
/// Frames. A device reports its tip in its own *device frame* [m] (for a Touch: origin at the
/// centre of the workspace, y up, z towards the user) and takes forces in that frame [N].
/// The cloth lives in the *scene frame* [m]. WorkspaceTransform is the one place where the two
/// meet: p_scene = offset + scale · R · p_device. Forces are never scaled (the hand feels
/// Newtons); they are only rotated back, F_device = Rᵀ · F_scene.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <string_view>

namespace costume::haptics {

/// The device models we know the force and stiffness limits of.
enum class DeviceModel : std::uint8_t {
  kTouch,        ///< 3D Systems Touch (formerly Phantom Omni successor).
  kOmni,         ///< SensAble Phantom Omni.
  kDesktop,      ///< SensAble Phantom Desktop.
  kCyberGrasp,   ///< CyberGlove Systems CyberGrasp exoskeleton (per finger).
  kSimulated,    ///< SimulatedDevice: the scripted virtual hand.
  kMouse,        ///< MouseDevice: the GUI pointer, renders no force.
  kLogPlayback,  ///< LogPlaybackDevice: replays a recorded device log.
};

/// "touch", "omni", "desktop", "cybergrasp", "simulated", "mouse" or "log_playback".
const char* DeviceModelName(DeviceModel model);

/// What a device can render. Forces beyond max_force and a rendered stiffness beyond
/// max_stiffness make a device buzz, overheat or go unstable; force_safety.h enforces both.
struct DeviceLimits {
  /// Largest force magnitude the device may be sent [N] > 0.
  double max_force = 3.3;
  /// Largest rendered stiffness, change of force per tip displacement [N/m] > 0.
  double max_stiffness = 400.0;
};

/// The built-in table:
///   Touch        3.3 N /  400 N/m  (vendor figures)
///   Omni         3.3 N /  700 N/m  (vendor figures)
///   Desktop      7.9 N / 1000 N/m  (vendor figures)
///   CyberGrasp    12 N /  500 N/m  (12 N per finger is the vendor figure; the vendor gives no
///                                   stiffness, 500 N/m is our conservative choice)
///   Simulated     10 N / 2000 N/m  (no hardware to protect: wide enough never to mask the
///                                   physics under test, still finite so the safety path runs)
///   Mouse        3.3 N /  400 N/m  (renders nothing; the GUI shows what a Touch would feel)
///   LogPlayback  3.3 N /  400 N/m  (as a Touch; a log replays forces computed for one)
/// Never throws; never allocates.
DeviceLimits LimitsFor(DeviceModel model);

/// Button bits in DeviceState::buttons, whatever the device's own numbering.
enum DeviceButton : std::uint32_t {
  kButtonGrab = 1u << 0,          ///< Held: the sphere grabs the cloth (Touch: front button).
  kButtonStretchRelief = 1u << 1, ///< Pressed: eliminate stretch energy (Touch: rear button).
};

/// One sample of a device, in the device frame.
struct DeviceState {
  /// Device time of the sample [s]; monotonic per device, origin device-specific.
  double time = 0.0;
  /// Tip position in the device frame [m].
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  /// Tip orientation in the device frame (unit quaternion).
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  /// Tip velocity in the device frame [m/s].
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  /// DeviceButton bits.
  std::uint32_t buttons = 0;
};

/// What went wrong in a hot-path device call. Read and Write return it instead of throwing
/// or allocating a message; HapticTick counts each kind.
enum class DeviceFault : std::uint8_t {
  kNone = 0,
  kNotOpen,        ///< Read/Write before Open or after Close. Remedy: Open the device.
  kNoData,         ///< No sample yet (the servo thread or GUI has not delivered one).
  kEndOfData,      ///< A scripted or recorded device ran past its last sample (holds it).
  kCommunication,  ///< The vendor SDK reported an error in its servo loop.
  kNonFinite,      ///< A non-finite value was offered or read; it was replaced by zero.
};

/// "none", "not_open", "no_data", "end_of_data", "communication" or "non_finite".
const char* DeviceFaultName(DeviceFault fault);

/// Result of Open and Close: success, or a message a user can act on (names the device and
/// the vendor's error code where there is one). Devices never fail silently (contrast chai3d).
struct DeviceStatus {
  bool ok = true;
  std::string message;
  static DeviceStatus Ok() { return {}; }
  static DeviceStatus Error(std::string text) { return {false, std::move(text)}; }
};

/// A haptic device. Open/Close run outside the tick (they may allocate, block and talk to
/// drivers). Read/Write run inside the 1 kHz tick: they never throw, never allocate, never
/// block on a lock held by another thread. Implementations are used from one thread at a time
/// (the tick), except where a class documents a second, producer thread (MouseDevice, the
/// vendor servo bridges).
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  /// Human-readable name for messages ("simulated 'pull.traj'", "OpenHaptics 'Default Device'").
  virtual std::string name() const = 0;
  /// Which row of the limits table applies.
  virtual DeviceModel model() const = 0;
  /// Force and stiffness limits; LimitsFor(model()) unless the device reports its own.
  virtual DeviceLimits limits() const { return LimitsFor(model()); }
  /// Connects and starts the device. Calling Open on an open device is a no-op returning Ok.
  virtual DeviceStatus Open() = 0;
  /// Sends zero force and disconnects. Closing a closed device is a no-op returning Ok.
  virtual DeviceStatus Close() = 0;
  /// Latest sample into `state` (device frame). On a fault `state` keeps a safe value (the
  /// last good sample or zeros) and the fault says why. Never throws; never allocates.
  virtual DeviceFault Read(DeviceState& state) = 0;
  /// Commands `force` [N] in the device frame. Non-finite components are refused (zero force
  /// sent, kNonFinite returned). Implementations clamp to limits().max_force as a last line
  /// of defence; force_safety.h does the real work. Never throws; never allocates.
  virtual DeviceFault Write(const Eigen::Vector3d& force) = 0;
};

/// Farthest a device's tip may be from its origin in a trajectory or a log [m]: desktop
/// devices reach some 0.2 m and gloves an arm's length; at WorkspaceTransform::kMaxScale
/// this spans the scene's ±10 km (sim::kMaxCoordinate).
inline constexpr double kMaxDeviceCoordinate = 10.0;

/// Where device and scene meet: p_scene = offset + scale · rotation · p_device.
/// scale > 0 maps device metres onto scene metres (a Touch has a ~16 cm workspace, a costume
/// is ~1.5 m tall: a scale of 5–10 is usual). Because positions are scaled and forces are not,
/// a stiffness K in the scene is felt as K · scale at the device; force_safety.h therefore
/// works in the device frame.
struct WorkspaceTransform {
  /// Scene metres per device metre (> 0).
  double scale = 1.0;
  /// Scene position of the device-frame origin [m].
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  /// Rotation from device axes to scene axes (orthonormal, det = +1).
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();

  /// Tip position in the scene [m]. Never throws; never allocates.
  Eigen::Vector3d PositionToScene(const Eigen::Vector3d& p_device) const {
    return offset + scale * (rotation * p_device);
  }
  /// Tip velocity in the scene [m/s].
  Eigen::Vector3d VelocityToScene(const Eigen::Vector3d& v_device) const {
    return scale * (rotation * v_device);
  }
  /// A scene point [m] in the device frame [m] (the inverse of PositionToScene).
  Eigen::Vector3d PositionToDevice(const Eigen::Vector3d& p_scene) const {
    return rotation.transpose() * (p_scene - offset) / scale;
  }
  /// A displacement in the scene [m] seen in the device frame [m].
  Eigen::Vector3d DisplacementToDevice(const Eigen::Vector3d& d_scene) const {
    return rotation.transpose() * d_scene / scale;
  }
  /// A scene-frame force [N] expressed in the device frame [N] (rotated, not scaled).
  Eigen::Vector3d ForceToDevice(const Eigen::Vector3d& f_scene) const {
    return rotation.transpose() * f_scene;
  }
  /// Bounds of `scale` [-]: a desktop device's 10–20 cm of travel then spans from a tenth of
  /// a millimetre to some 200 m of scene. Beyond the large end a device's reach leaves the
  /// scene's ±10 km (sim::kMaxCoordinate); beyond the small end a millimetre of scene asks
  /// for more than a metre of device travel (PositionToDevice), out of any device's reach.
  static constexpr double kMinScale = 1e-3;
  static constexpr double kMaxScale = 1e3;
  /// Throws costume::sim::InputError unless scale lies in [kMinScale, kMaxScale], offset
  /// within ±sim::kMaxCoordinate and rotation is orthonormal with determinant +1 (within
  /// 1e-9). The fields are named `what` + ".scale" etc., or `scale_field` and
  /// `offset_field` as given (a program's options: "--scale").
  void Validate(const std::string& what, const std::string& scale_field = "",
                const std::string& offset_field = "") const;
};

/// Replaces non-finite components by zero and scales `force` down to at most `max_force`
/// [N] in magnitude, keeping its direction. Returns true when anything was changed.
/// The devices' last line of defence. Never throws; never allocates.
bool ClampForce(Eigen::Vector3d& force, double max_force);

}  // namespace costume::haptics
