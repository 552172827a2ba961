#pragma once
/// @file
/// A CyberGrasp exoskeleton with its CyberGlove and 6-DOF tracker through the VirtualHand SDK
/// (vhtIOConn, vhtCyberGlove, vhtTracker, vhtCyberGrasp, vhtHumanHand). Compiled only when CMake
/// finds the SDK (option COSTUME_WITH_CYBERGRASP). The SDK's calls talk to the device manager
/// over the network and may block or throw (vhtBaseException*), so they run on this class's own
/// thread at up to 1 kHz; values cross to the tick through CyberGraspBridge (tested without the
/// SDK). Mapping, units and force levels: cybergrasp_bridge.h.

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "haptic_server/cybergrasp_bridge.h"

class vhtCyberGlove;
class vhtTracker;
class vhtCyberGrasp;
class vhtHumanHand;

namespace costume::haptics {

class CyberGraspDevice final : public CyberGraspBridge {
 public:
  explicit CyberGraspDevice(const CyberGraspCalibration& calibration = {});
  ~CyberGraspDevice() override;

  std::string name() const override { return "CyberGrasp (VirtualHand SDK)"; }
  /// Connects glove, tracker and grasp through the device manager's default connections
  /// (vhtIOConn::getDefault), builds the vhtHumanHand and starts the update thread. Returns the
  /// SDK's exception message on failure.
  DeviceStatus Open() override;
  /// Zero force, stops the thread, disconnects.
  DeviceStatus Close() override;

 private:
  void UpdateLoop();
  void Release();

  vhtCyberGlove* glove_ = nullptr;
  vhtTracker* tracker_ = nullptr;
  vhtCyberGrasp* grasp_ = nullptr;
  vhtHumanHand* hand_ = nullptr;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace costume::haptics
