#include "bus/receive_filter.h"

#include <chrono>

namespace costume::bus {

namespace {
// LCM_SHORT_MESSAGE_MAX_SIZE in lcm_udpm.c: channel name, its NUL and the payload.
constexpr int kShortMessageMaxSize = 65'499;
}  // namespace

int MaxDatagramPayload(const std::string& channel) {
  return kShortMessageMaxSize - static_cast<int>(channel.size()) - 1;
}

std::int64_t NowUtime() {
  using namespace std::chrono;
  return duration_cast<microseconds>(system_clock::now().time_since_epoch()).count();
}

ReceiveFilter::ReceiveFilter(const std::string& channel, ReceivePolicy policy)
    : policy_(std::move(policy)) {
  if (policy_.max_bytes <= 0) policy_.max_bytes = MaxDatagramPayload(channel);
  if (!policy_.clock) policy_.clock = NowUtime;
}

bool ReceiveFilter::AcceptSize(std::size_t bytes) {
  if (bytes <= static_cast<std::size_t>(policy_.max_bytes)) return true;
  ++counts_.oversized;
  return false;
}

bool ReceiveFilter::AcceptStamp(std::int64_t utime, std::int64_t seq) {
  if (policy_.max_age_us > 0 || policy_.max_lead_us > 0) {
    const std::int64_t now = policy_.clock();
    // Compare differences, not now ± limit, so that extreme stamps cannot overflow.
    const bool too_old = policy_.max_age_us > 0 && utime < now &&
                         static_cast<std::uint64_t>(now) - static_cast<std::uint64_t>(utime) >
                             static_cast<std::uint64_t>(policy_.max_age_us);
    const bool too_new = policy_.max_lead_us > 0 && utime > now &&
                         static_cast<std::uint64_t>(utime) - static_cast<std::uint64_t>(now) >
                             static_cast<std::uint64_t>(policy_.max_lead_us);
    if (too_old || too_new) {
      ++counts_.stale;
      return false;
    }
  }
  if (policy_.require_increasing_seq && has_last_ && seq <= last_seq_) {
    if (utime <= last_utime_) {
      ++counts_.out_of_order;
      return false;
    }
    ++counts_.sender_restarts;
  }
  has_last_ = true;
  last_utime_ = utime;
  last_seq_ = seq;
  ++counts_.accepted;
  return true;
}

}  // namespace costume::bus
