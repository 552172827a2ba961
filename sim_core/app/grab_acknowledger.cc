#include "sim_core/app/grab_acknowledger.h"

#include "bus/channels.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/grab_ack.hpp"

namespace costume::sim_app {

GrabAcknowledger::GrabAcknowledger(const std::string& url, bus::Reach reach)
    : bus_(std::make_unique<bus::LcmBus>(url, reach)) {
  // Subscribed and published from the thread only, after construction.
  thread_ = std::thread([this] {
    bus::Publisher<costume_lcm::grab_ack> publisher(*bus_, bus::kGrabAckChannel);
    costume_lcm::grab_ack ack{};
    bus::Subscribe<costume_lcm::grab>(*bus_, bus::kGrabChannel, [&](const costume_lcm::grab& g) {
      ack.utime = bus::NowUtime();
      ack.grab_seq = g.seq;
      ack.grab_utime = g.utime;
      ack.grab_id = g.grab_id;
      ack.device_id = g.device_id;
      if (publisher.Publish(ack)) num_acks_.fetch_add(1, std::memory_order_relaxed);
    });
    while (!stop_.load(std::memory_order_relaxed)) bus_->HandleSubscriptions(10);
  });
}

GrabAcknowledger::~GrabAcknowledger() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

}  // namespace costume::sim_app
