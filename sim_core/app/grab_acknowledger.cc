#include "sim_core/app/grab_acknowledger.h"

#include <pthread.h>
#include <sched.h>

#include <cstring>
#include <future>

#include "bus/channels.h"
#include "bus/typed_bus.h"
#include "lcm_types/costume_lcm/grab.hpp"
#include "lcm_types/costume_lcm/grab_ack.hpp"

namespace costume::sim_app {

namespace {

/// SCHED_FIFO at `priority` for the calling thread: "" when granted, else why not.
std::string TryFifo(int priority) {
  sched_param param{};
  param.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (error == 0) return "";
  return "grab acknowledger: SCHED_FIFO priority " + std::to_string(priority) + " refused: " +
         std::strerror(error) + "; grant CAP_SYS_NICE (setcap cap_sys_nice+ep "
         "costume_sim_server) or an rtprio limit. Acks at normal priority.";
}

}  // namespace

GrabAcknowledger::GrabAcknowledger(const std::string& url, bus::Reach reach, int priority)
    : bus_(std::make_unique<bus::LcmBus>(url, reach)) {
  std::promise<void> asked;
  std::future<void> done = asked.get_future();
  // Subscribed and published from the thread only, after construction.
  thread_ = std::thread([this, priority, &asked] {
    if (priority > 0) priority_refusal_ = TryFifo(priority);
    asked.set_value();  // `asked` is not touched after this
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
  done.wait();
}

GrabAcknowledger::~GrabAcknowledger() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

}  // namespace costume::sim_app
