#pragma once
/// @file
/// Commands that survive a dropped datagram. A command (lcm_types/command.lcm) is sent once
/// over UDP; one lost datagram used to lose it (an integration run lost the only
/// stretch-elimination command). CommandResender numbers and publishes commands like a
/// bus::Publisher, keeps every command not yet acknowledged, and resends it with its original
/// seq *and original utime* until the simulation server shows it taken in: each cloth_frame
/// carries command_seq / haptic_command_seq, the seq of the last command it took in from each
/// channel (acknowledgement: that seq >= the command's).
///
/// Why the original utime: the receive filter (receive_filter.h) accepts a repeated seq with a
/// newer utime as a sender restart, so a refreshed utime would apply a command twice. With
/// both stamps unchanged a copy reaching a server that already took the command in is dropped
/// as out of order (counted in status.dropped_out_of_order: expected after a resend, not an
/// alarm), and all copies go out within max_resends · period (0.5 s by default) of the
/// original, well within the filter's 1 s max age.
///
/// Order: the receive filter keeps only increasing seqs, so a lost command overtaken by a
/// later one could never be taken in again. Send therefore resends the pending commands before
/// publishing a new one, keeping the copies in seq order on the wire.

#include <cstdint>
#include <string>
#include <vector>

#include "bus/message_bus.h"
#include "lcm_types/costume_lcm/command.hpp"

namespace costume::bus {

/// How often and how long unacknowledged commands are resent.
struct ResendPolicy {
  /// Time between copies of an unacknowledged command [µs] > 0.
  std::int64_t period_us = 100'000;
  /// Copies after the first before giving up (>= 0). period_us · max_resends must stay well
  /// below the receivers' max age (ReceivePolicy::max_age_us, 1 s).
  int max_resends = 5;
  /// Commands kept unacknowledged at most (> 0); a new command beyond it gives the oldest up.
  int max_pending = 32;
  /// Throws costume::sim::InputError naming the field, value and allowed range.
  void Validate() const;
};

/// What a CommandResender did since construction.
struct ResendCounts {
  std::int64_t num_sent = 0;          ///< commands published (first copies)
  std::int64_t num_resent = 0;        ///< further copies published
  std::int64_t num_acknowledged = 0;  ///< commands a cloth_frame showed taken in
  std::int64_t num_given_up = 0;      ///< commands dropped after max_resends copies
  std::int64_t num_refused = 0;       ///< publishes the bus refused (first copies and resends)
};

/// The sender side of one command channel (one sender per channel). One thread only.
class CommandResender {
 public:
  /// `bus` must outlive this. Throws InputError for an invalid channel or policy.
  CommandResender(MessageBus& bus, std::string channel, ResendPolicy policy = {});

  /// Resends the pending commands (original stamps), then sets message.seq to the next seq
  /// and publishes it; `now_us` [µs, NowUtime's clock] times its resends; the caller sets
  /// message.utime. Returns false when the bus refused the first copy (the command is still
  /// kept and resent: a transient refusal is a lost datagram too).
  bool Send(costume_lcm::command& message, std::int64_t now_us);
  /// A cloth_frame's command_seq (or haptic_command_seq) for this channel: every pending
  /// command with seq <= `taken_seq` is acknowledged and never resent.
  void Acknowledge(std::int64_t taken_seq);
  /// Resends every pending command whose last copy is period_us old at `now_us` [µs]; gives
  /// up on those that had max_resends copies. Returns the commands given up in this call
  /// (their kind and seq are in given_up()).
  int ResendDue(std::int64_t now_us);

  /// Whether a command waits for its acknowledgement.
  bool has_pending() const { return !pending_.empty(); }
  const ResendCounts& counts() const { return counts_; }
  /// The seq the next command gets.
  std::int64_t next_seq() const { return next_seq_; }
  /// The commands the last ResendDue (or Send) gave up (for a warning naming kind and seq).
  const std::vector<costume_lcm::command>& given_up() const { return given_up_; }

 private:
  struct Pending {
    costume_lcm::command message;
    std::int64_t last_sent_us = 0;
    int resends = 0;
  };
  bool PublishCopy(const costume_lcm::command& message);

  MessageBus& bus_;
  std::string channel_;
  ResendPolicy policy_;
  std::vector<Pending> pending_;  // in seq order
  std::vector<costume_lcm::command> given_up_;
  std::vector<std::uint8_t> buffer_;
  std::int64_t next_seq_ = 0;
  ResendCounts counts_;
};

}  // namespace costume::bus
