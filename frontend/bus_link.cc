#include "frontend/bus_link.h"

#include "bus/channels.h"
#include "bus/typed_bus.h"

namespace costume::frontend {

void RegisterMessageTypes() {
  qRegisterMetaType<costume_lcm::cloth_frame>();
  qRegisterMetaType<costume_lcm::device_state>();
  qRegisterMetaType<costume_lcm::feedback>();
  qRegisterMetaType<costume_lcm::status>();
}

BusLink::BusLink(bus::MessageBus& bus, QObject* parent) : QObject(parent), bus_(bus) {
  RegisterMessageTypes();
  counts_.push_back(bus::Subscribe<costume_lcm::cloth_frame>(
      bus_, bus::kClothFrameChannel,
      [this](const costume_lcm::cloth_frame& m) { emit clothChunk(m); }));
  counts_.push_back(bus::Subscribe<costume_lcm::device_state>(
      bus_, bus::kDeviceStateChannel,
      [this](const costume_lcm::device_state& m) { emit deviceState(m); }));
  counts_.push_back(bus::Subscribe<costume_lcm::feedback>(
      bus_, bus::kFeedbackChannel, [this](const costume_lcm::feedback& m) { emit feedback(m); }));
  counts_.push_back(bus::Subscribe<costume_lcm::status>(
      bus_, bus::kSimStatusChannel, [this](const costume_lcm::status& m) { emit simStatus(m); }));
  counts_.push_back(bus::Subscribe<costume_lcm::status>(
      bus_, bus::kHapticStatusChannel,
      [this](const costume_lcm::status& m) { emit hapticStatus(m); }));
}

int BusLink::Poll(int timeout_ms) { return bus_.HandleSubscriptions(timeout_ms); }

std::int64_t BusLink::dropped() const {
  std::int64_t total = 0;
  for (const auto& counts : counts_) total += counts->dropped();
  return total;
}

BusThread::BusThread(BusLink& link, QObject* parent) : QThread(parent), link_(link) {}

BusThread::~BusThread() { Stop(); }

void BusThread::Stop() {
  stop_.store(true);
  wait();
}

void BusThread::run() {
  // 50 ms bounds how long Stop waits; messages are dispatched as soon as they arrive.
  while (!stop_.load()) {
    if (link_.Poll(50) < 0) msleep(50);
  }
}

}  // namespace costume::frontend
