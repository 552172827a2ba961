#pragma once
/// @file
/// Typed publishing and receiving of lcm-gen messages (lcm_types/) over a MessageBus.
/// Every message type carries `int64_t utime` [µs since the Unix epoch, sender's clock] and
/// `int64_t seq` (per channel, +1 per message). Receiving decodes with the generated decode
/// and drops, counting them, messages that are malformed, oversized, stale or out of order
/// (receive_filter.h): a bad datagram never reaches a handler and never crashes a process.

#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "bus/message_bus.h"
#include "bus/message_checks.h"
#include "bus/receive_filter.h"

namespace costume::bus {

/// Encodes `message` as it is (utime and seq untouched) into `buffer` (resized, capacity
/// kept) and publishes it on `channel`. Returns false, publishing nothing, when the array
/// counts do not match the vectors (CountsMatch), the encoding is longer than `max_bytes`
/// [bytes] (<= 0: MaxDatagramPayload(channel)), or the bus refused it. Throws InputError
/// only for an invalid channel name.
template <class Message>
bool Publish(MessageBus& bus, const std::string& channel, const Message& message,
             std::vector<std::uint8_t>& buffer, int max_bytes = 0) {
  if (!CountsMatch(message)) return false;
  const int size = message.getEncodedSize();
  if (size > (max_bytes > 0 ? max_bytes : MaxDatagramPayload(channel))) return false;
  buffer.resize(static_cast<std::size_t>(size));
  if (message.encode(buffer.data(), 0, size) != size) return false;
  return bus.Publish(channel, buffer);
}

/// Publish with a buffer of its own (one allocation per call).
template <class Message>
bool Publish(MessageBus& bus, const std::string& channel, const Message& message,
             int max_bytes = 0) {
  std::vector<std::uint8_t> buffer;
  return Publish(bus, channel, message, buffer, max_bytes);
}

/// Publishes messages of one type on one channel, numbering them: the sender side of a
/// channel (one sender per channel). Keeps its encoding buffer, so publishing allocates only
/// when a message is larger than every earlier one.
template <class Message>
class Publisher {
 public:
  /// `max_bytes` [bytes] as in Publish. Throws InputError for an invalid channel name.
  Publisher(MessageBus& bus, std::string channel, int max_bytes = 0)
      : bus_(bus), channel_(std::move(channel)), max_bytes_(max_bytes) {
    RequireValidChannel(channel_);
  }

  /// Sets message.seq to the next sequence number (0, 1, 2, ... over successful publishes)
  /// and publishes; the caller sets message.utime (the time the data describes, e.g.
  /// NowUtime() at sampling). Returns false and counts a refusal as Publish does.
  /// Never throws.
  bool Publish(Message& message) {
    message.seq = next_seq_;
    if (!bus::Publish(bus_, channel_, message, buffer_, max_bytes_)) {
      ++num_refused_;
      return false;
    }
    ++next_seq_;
    return true;
  }

  const std::string& channel() const { return channel_; }
  /// The seq the next published message gets.
  std::int64_t next_seq() const { return next_seq_; }
  /// Messages refused since construction.
  std::int64_t num_refused() const { return num_refused_; }

 private:
  MessageBus& bus_;
  std::string channel_;
  int max_bytes_;
  std::vector<std::uint8_t> buffer_;
  std::int64_t next_seq_ = 0;
  std::int64_t num_refused_ = 0;
};

/// Decodes a whole payload into `message` with lcm-gen's decode. False when it does not
/// decode (wrong fingerprint, truncated, trailing bytes, negative or impossible array counts,
/// which lcm-gen's code reports by throwing from std::vector::resize). Never throws.
template <class Message>
bool Decode(std::span<const std::uint8_t> payload, Message& message) {
  if (payload.size() > static_cast<std::size_t>(INT32_MAX)) return false;
  const int size = static_cast<int>(payload.size());
  try {
    return message.decode(payload.data(), 0, size) == size;
  } catch (const std::exception&) {
    return false;
  }
}

/// Subscribes `handler` to `channel`: each payload is size-checked, decoded into a fresh
/// Message (so no array keeps a previous message's values), age- and order-checked under
/// `policy`, and only then handed over. Returns the subscription's counters, updated inside
/// bus.HandleSubscriptions (read them from that thread). Throws InputError for an invalid
/// channel name; exceptions from `handler` propagate from HandleSubscriptions.
template <class Message>
std::shared_ptr<const ReceiveCounts> Subscribe(MessageBus& bus, const std::string& channel,
                                               std::function<void(const Message&)> handler,
                                               ReceivePolicy policy = {}) {
  auto filter = std::make_shared<ReceiveFilter>(channel, std::move(policy));
  bus.Subscribe(channel, [filter, handler = std::move(handler)](
                             std::span<const std::uint8_t> payload) {
    if (!filter->AcceptSize(payload.size())) return;
    Message message{};
    if (!Decode(payload, message)) {
      filter->CountMalformed();
      return;
    }
    if (!filter->AcceptStamp(message.utime, message.seq)) return;
    handler(message);
  });
  return {filter, &filter->counts()};
}

}  // namespace costume::bus
