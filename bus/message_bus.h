#pragma once
/// @file
/// The message bus the processes talk over, as a small interface a test can drive
/// (STYLE.md §4; after drake's lcm/drake_lcm_interface.h). LcmBus (lcm_bus.h) is the one
/// implementation: over UDP multicast between processes, over LCM's in-process `memq://`
/// provider in unit tests. Typed publishing and receiving with the drop counters live in
/// typed_bus.h; channel names in channels.h.

#include <cstdint>
#include <functional>
#include <span>
#include <string>

namespace costume::bus {

/// Largest channel name LCM carries [characters] (LCM_MAX_CHANNEL_NAME_LENGTH).
inline constexpr int kMaxChannelLength = 63;

/// Throws costume::sim::InputError unless `channel` is 1 to kMaxChannelLength characters from
/// [A-Za-z0-9_]. LCM subscribes by regular expression; refusing every other character makes
/// a subscription match exactly one channel.
void RequireValidChannel(const std::string& channel);

/// Publish/subscribe of raw payloads by channel name.
/// Threading: Publish may be called from any thread; Subscribe and HandleSubscriptions from
/// one thread (the process's I/O thread), and handlers run inside HandleSubscriptions.
class MessageBus {
 public:
  /// Receives one message's payload (the encoded LCM message) [bytes]; the span is valid
  /// only during the call.
  using Handler = std::function<void(std::span<const std::uint8_t> payload)>;

  virtual ~MessageBus() = default;

  /// Sends `payload` on `channel`. Returns false when the transport refused it (a send
  /// error); never throws for that. Throws InputError for an invalid channel name.
  virtual bool Publish(const std::string& channel, std::span<const std::uint8_t> payload) = 0;

  /// Calls `handler` for each message later received on exactly `channel`, from within
  /// HandleSubscriptions. Subscriptions last as long as the bus. Throws InputError for an
  /// invalid channel name.
  virtual void Subscribe(const std::string& channel, Handler handler) = 0;

  /// Waits up to `timeout_ms` [ms] (<= 0: does not wait) for a message, then dispatches every
  /// message that has arrived; returns how many were dispatched (0 on timeout), or -1 when
  /// the transport failed. An exception thrown by a handler propagates from here, after the
  /// message that raised it.
  virtual int HandleSubscriptions(int timeout_ms) = 0;
};

}  // namespace costume::bus
