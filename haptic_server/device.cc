#include "haptic_server/device.h"

#include <cmath>

#include "sim_core/common/input_error.h"

namespace costume::haptics {

const char* DeviceModelName(DeviceModel model) {
  switch (model) {
    case DeviceModel::kTouch: return "touch";
    case DeviceModel::kOmni: return "omni";
    case DeviceModel::kDesktop: return "desktop";
    case DeviceModel::kCyberGrasp: return "cybergrasp";
    case DeviceModel::kSimulated: return "simulated";
    case DeviceModel::kMouse: return "mouse";
    case DeviceModel::kLogPlayback: return "log_playback";
  }
  return "unknown";
}

DeviceLimits LimitsFor(DeviceModel model) {
  switch (model) {
    case DeviceModel::kTouch: return {3.3, 400.0};
    case DeviceModel::kOmni: return {3.3, 700.0};
    case DeviceModel::kDesktop: return {7.9, 1000.0};
    case DeviceModel::kCyberGrasp: return {12.0, 500.0};
    case DeviceModel::kSimulated: return {10.0, 2000.0};
    case DeviceModel::kMouse: return {3.3, 400.0};
    case DeviceModel::kLogPlayback: return {3.3, 400.0};
  }
  return {3.3, 400.0};  // the weakest device: safe if a new enumerator is forgotten
}

const char* DeviceFaultName(DeviceFault fault) {
  switch (fault) {
    case DeviceFault::kNone: return "none";
    case DeviceFault::kNotOpen: return "not_open";
    case DeviceFault::kNoData: return "no_data";
    case DeviceFault::kEndOfData: return "end_of_data";
    case DeviceFault::kCommunication: return "communication";
    case DeviceFault::kNonFinite: return "non_finite";
  }
  return "unknown";
}

void WorkspaceTransform::Validate(const std::string& what, const std::string& scale_field,
                                  const std::string& offset_field) const {
  sim::RequireInRange(scale_field.empty() ? what + ".scale" : scale_field, scale, kMinScale,
                      kMaxScale, "");
  for (int i = 0; i < 3; ++i) {
    sim::RequireInRange((offset_field.empty() ? what + ".offset" : offset_field) + "[" +
                            std::to_string(i) + "]",
                        offset[i], -sim::kMaxCoordinate, sim::kMaxCoordinate, "m");
  }
  const double orthonormality = (rotation.transpose() * rotation -
                                 Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double det = rotation.determinant();
  if (!(orthonormality < 1e-9 && std::abs(det - 1.0) < 1e-9)) {
    throw sim::InputError(what + ".rotation is not a rotation: |RᵀR − I|max = " +
                          sim::FormatValue(orthonormality) + ", det = " +
                          sim::FormatValue(det) + " (allowed: RᵀR = I and det = +1 within 1e-9)");
  }
}

bool ClampForce(Eigen::Vector3d& force, double max_force) {
  if (!force.allFinite()) {
    force.setZero();
    return true;
  }
  const double magnitude = force.norm();
  if (magnitude <= max_force) return false;
  force *= max_force / magnitude;
  return true;
}

}  // namespace costume::haptics
