#include "haptic_server/cybergrasp_device.h"

#include <vhandtk/vhtBase.h>

#include <ctime>

namespace costume::haptics {

namespace {

double MonotonicSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Mean of a finger's three joint angles [rad] (metacarpal, proximal, distal).
double FingerFlexion(vhtCyberGlove& glove, GHM::Fingers finger) {
  return (glove.getData(finger, GHM::metacarpal) + glove.getData(finger, GHM::proximal) +
          glove.getData(finger, GHM::distal)) / 3.0;
}

}  // namespace

CyberGraspDevice::CyberGraspDevice(const CyberGraspCalibration& calibration)
    : CyberGraspBridge(calibration) {}

CyberGraspDevice::~CyberGraspDevice() { Close(); }

DeviceStatus CyberGraspDevice::Open() {
  if (running_.load()) return DeviceStatus::Ok();
  try {
    glove_ = new vhtCyberGlove(vhtIOConn::getDefault(vhtIOConn::glove));
    tracker_ = new vhtTracker(vhtIOConn::getDefault(vhtIOConn::tracker));
    grasp_ = new vhtCyberGrasp(vhtIOConn::getDefault(vhtIOConn::grasp));
    hand_ = new vhtHumanHand(glove_, tracker_, grasp_);
  } catch (vhtBaseException* e) {
    const std::string message = e->getMessage();
    delete e;
    Release();
    return DeviceStatus::Error(name() + ": connecting failed: " + message +
                               "; is the device manager running and the hardware on?");
  }
  CyberGraspBridge::Open();
  running_.store(true);
  thread_ = std::thread([this] { UpdateLoop(); });
  return DeviceStatus::Ok();
}

DeviceStatus CyberGraspDevice::Close() {
  CyberGraspBridge::Close();  // levels drop to zero on the next update
  if (running_.exchange(false) && thread_.joinable()) thread_.join();
  Release();
  return DeviceStatus::Ok();
}

void CyberGraspDevice::Release() {
  if (grasp_ != nullptr) {
    double zero[5] = {0, 0, 0, 0, 0};
    try {
      grasp_->setForce(zero);
    } catch (vhtBaseException* e) {
      delete e;
    }
  }
  if (hand_ != nullptr) {
    try {
      hand_->disconnect();
    } catch (vhtBaseException* e) {
      delete e;
    }
  }
  // The SDK headers we could read do not say whether vhtHumanHand deletes the glove, tracker
  // and grasp it was given; leaking those three small objects at Close is safer than a double
  // delete. Check against the SDK's documentation when hardware is at hand.
  delete hand_;
  hand_ = nullptr;
  grasp_ = nullptr;
  tracker_ = nullptr;
  glove_ = nullptr;
}

void CyberGraspDevice::UpdateLoop() {
  const GHM::Fingers fingers[5] = {GHM::thumb, GHM::index, GHM::middle, GHM::ring, GHM::pinky};
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  while (running_.load(std::memory_order_relaxed)) {
    CyberGraspSample sample;
    sample.time = MonotonicSeconds();
    try {
      hand_->update();
      vht6DofDevice* receiver = tracker_->getLogicalDevice(0);
      const vht6DofDevice::Freedom axes[6] = {vht6DofDevice::xPos,   vht6DofDevice::yPos,
                                              vht6DofDevice::zPos,   vht6DofDevice::xAngle,
                                              vht6DofDevice::yAngle, vht6DofDevice::zAngle};
      for (int i = 0; i < 6; ++i) sample.tracker[i] = receiver->getRawData(axes[i]);
      for (int f = 0; f < 5; ++f) sample.finger_flexion[f] = FingerFlexion(*glove_, fingers[f]);
    } catch (vhtBaseException* e) {
      delete e;
      sample.error = true;
    }
    std::array<double, 5> levels = DeviceExchange(sample);
    try {
      grasp_->setForce(levels.data());
    } catch (vhtBaseException* e) {
      delete e;
    }
    next.tv_nsec += 1'000'000;  // 1 ms, absolute, as the haptic loop
    if (next.tv_nsec >= 1'000'000'000) {
      next.tv_nsec -= 1'000'000'000;
      ++next.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
  }
}

}  // namespace costume::haptics
