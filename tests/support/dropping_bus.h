#pragma once
/// @file
/// A MessageBus wrapper that loses chosen datagrams: the first `drop_first` publishes on one
/// channel never reach the bus (a lost UDP datagram); everything else is forwarded.

#include <span>
#include <string>

#include "bus/message_bus.h"

namespace costume::testing {

/// Forwards to `inner`, dropping the first `drop_first` publishes on `channel`.
class DroppingBus final : public bus::MessageBus {
 public:
  DroppingBus(bus::MessageBus& inner, std::string channel, int drop_first = 1)
      : inner_(inner), channel_(std::move(channel)), to_drop_(drop_first) {}
  bool Publish(const std::string& channel, std::span<const std::uint8_t> payload) override {
    if (channel == channel_) {
      ++published_;
      if (to_drop_ > 0) {
        --to_drop_;
        return true;  // "sent": the loss happens on the way
      }
    }
    return inner_.Publish(channel, payload);
  }
  void Subscribe(const std::string& channel, Handler handler) override {
    inner_.Subscribe(channel, std::move(handler));
  }
  int HandleSubscriptions(int timeout_ms) override {
    return inner_.HandleSubscriptions(timeout_ms);
  }
  /// Publishes on the channel so far, dropped ones included.
  int published() const { return published_; }

 private:
  bus::MessageBus& inner_;
  std::string channel_;
  int to_drop_;
  int published_ = 0;
};

}  // namespace costume::testing
