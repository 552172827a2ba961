#pragma once
/// @file
/// The checks a received message passes before its handler sees it: size, age and order.
/// Messages that fail are counted and dropped, never thrown about: a malformed, oversized,
/// stale or replayed datagram must not stop a process (issue 5, "Tests").

#include <cstdint>
#include <functional>
#include <string>

namespace costume::bus {

/// Largest LCM payload the UDP multicast provider sends on `channel` in one datagram
/// [bytes]: it needs channel name + 1 + payload <= 65,499. Larger payloads are fragmented,
/// and fragments were lost under load here (PLATFORM.md): cloth frames and patches are
/// therefore chunked (lcm_types/cloth_frame.lcm).
int MaxDatagramPayload(const std::string& channel);

/// Now on this machine's clock [µs since the Unix epoch]: what `utime` fields hold.
std::int64_t NowUtime();

/// What a subscriber accepts.
struct ReceivePolicy {
  /// Payloads longer than this are dropped undecoded [bytes]; <= 0: MaxDatagramPayload.
  int max_bytes = 0;
  /// Messages whose utime is older than now - max_age_us are dropped as stale [µs];
  /// <= 0 disables the check (a log replayed long after it was recorded).
  std::int64_t max_age_us = 1'000'000;
  /// Messages whose utime is later than now + max_lead_us are dropped as stale too (a sender
  /// clock far ahead, or a corrupt stamp that would block every later message) [µs];
  /// <= 0 disables the check.
  std::int64_t max_lead_us = 1'000'000;
  /// Drop a message whose seq does not exceed the last accepted one (late or duplicated),
  /// unless its utime is newer than the last accepted one: then the sender restarted
  /// (seq back at 0) and the message starts a new sequence. Assumes one sender per channel.
  bool require_increasing_seq = true;
  /// The clock for the age checks [µs since the Unix epoch]; empty: NowUtime.
  std::function<std::int64_t()> clock = nullptr;
};

/// Messages seen by one subscription since it was made.
struct ReceiveCounts {
  std::int64_t accepted = 0;         ///< handed to the handler
  std::int64_t malformed = 0;        ///< did not decode: wrong type or fingerprint, truncated,
                                     ///< trailing bytes, impossible array counts
  std::int64_t oversized = 0;        ///< longer than ReceivePolicy::max_bytes
  std::int64_t stale = 0;            ///< utime outside [now - max_age_us, now + max_lead_us]
  std::int64_t out_of_order = 0;     ///< seq not above the last accepted one
  std::int64_t sender_restarts = 0;  ///< accepted although seq went down (utime newer)

  /// Every message dropped, whatever the reason.
  std::int64_t dropped() const { return malformed + oversized + stale + out_of_order; }
};

/// The size, age and order checks of one subscription, counting what it drops.
/// Never throws; allocation-free.
class ReceiveFilter {
 public:
  /// `channel` sets the default size limit.
  ReceiveFilter(const std::string& channel, ReceivePolicy policy);

  /// True when a payload of `bytes` [bytes] may be decoded; counts it as oversized otherwise.
  bool AcceptSize(std::size_t bytes);
  /// Counts a payload that did not decode.
  void CountMalformed() { ++counts_.malformed; }
  /// True when a decoded message stamped (`utime` [µs], `seq`) passes the age and order
  /// checks; then it is counted as accepted and becomes the last accepted one.
  bool AcceptStamp(std::int64_t utime, std::int64_t seq);

  const ReceiveCounts& counts() const { return counts_; }

 private:
  ReceivePolicy policy_;
  ReceiveCounts counts_;
  bool has_last_ = false;
  std::int64_t last_utime_ = 0;
  std::int64_t last_seq_ = 0;
};

}  // namespace costume::bus
