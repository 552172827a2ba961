#pragma once
/// @file
/// The simulation server's receive thread for grab receipts: its own LCM instance on the
/// server's URL, subscribed to COSTUME_GRAB only, answering each grab that passes the receive
/// filter at once on COSTUME_GRAB_ACK (lcm_types/grab_ack.lcm). The haptic side measures the
/// transport round trip with it (tools/haptic_bench.cc) without the 60 Hz frame in the way:
/// the server's loop drains its own subscription only once per frame. It shares nothing with
/// SimServer (a separate socket, thread and filter), so it needs no locks.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "bus/lcm_bus.h"
#include "bus/receive_filter.h"

namespace costume::sim_app {

class GrabAcknowledger {
 public:
  /// Opens an LCM instance on `url` with `reach` (as bus::LcmBus, which throws InputError for
  /// a refused URL) and starts the thread, which first asks for SCHED_FIFO at `priority`
  /// (1..99; <= 0: stays at normal priority): the acks carry the haptic round trip, so the
  /// thread should not wait behind the 60 Hz frame's work. Returns once the thread has asked.
  GrabAcknowledger(const std::string& url, bus::Reach reach, int priority = 0);
  /// Stops the thread (within ~10 ms) and joins it.
  ~GrabAcknowledger();
  GrabAcknowledger(const GrabAcknowledger&) = delete;
  GrabAcknowledger& operator=(const GrabAcknowledger&) = delete;

  /// Acknowledgements published since start (any thread).
  std::int64_t num_acks() const { return num_acks_.load(std::memory_order_relaxed); }
  /// Why the priority asked for was refused (errno text and remedy); empty when it was
  /// granted or none was asked for.
  const std::string& priority_refusal() const { return priority_refusal_; }

 private:
  std::unique_ptr<bus::LcmBus> bus_;
  std::atomic<bool> stop_{false};
  std::atomic<std::int64_t> num_acks_{0};
  std::string priority_refusal_;  ///< written by the thread before the constructor returns
  std::thread thread_;
};

}  // namespace costume::sim_app
