#include "bus/command_resender.h"

#include <algorithm>
#include <utility>

#include "bus/typed_bus.h"
#include "sim_core/common/input_error.h"

namespace costume::bus {

void ResendPolicy::Validate() const {
  if (!(period_us > 0) || max_resends < 0 || max_pending <= 0) {
    throw sim::InputError("ResendPolicy: period_us = " + std::to_string(period_us) +
                          " (> 0), max_resends = " + std::to_string(max_resends) +
                          " (>= 0), max_pending = " + std::to_string(max_pending) + " (> 0)");
  }
}

namespace {

ResendPolicy Validated(const ResendPolicy& policy) {
  policy.Validate();
  return policy;
}

}  // namespace

CommandResender::CommandResender(MessageBus& bus, std::string channel, ResendPolicy policy)
    : bus_(bus), channel_(std::move(channel)), policy_(Validated(policy)) {
  RequireValidChannel(channel_);
  pending_.reserve(static_cast<std::size_t>(policy_.max_pending));
}

bool CommandResender::PublishCopy(const costume_lcm::command& message) {
  if (Publish(bus_, channel_, message, buffer_)) return true;
  ++counts_.num_refused;
  return false;
}

bool CommandResender::Send(costume_lcm::command& message, std::int64_t now_us) {
  given_up_.clear();
  for (Pending& p : pending_) {
    if (PublishCopy(p.message)) ++counts_.num_resent;
  }
  if (static_cast<int>(pending_.size()) >= policy_.max_pending) {
    given_up_.push_back(pending_.front().message);
    ++counts_.num_given_up;
    pending_.erase(pending_.begin());
  }
  message.seq = next_seq_++;
  const bool published = PublishCopy(message);
  if (published) ++counts_.num_sent;
  pending_.push_back({message, now_us, 0});
  return published;
}

void CommandResender::Acknowledge(std::int64_t taken_seq) {
  const auto acknowledged = std::find_if(pending_.begin(), pending_.end(), [&](const Pending& p) {
    return p.message.seq > taken_seq;
  });
  counts_.num_acknowledged += acknowledged - pending_.begin();
  pending_.erase(pending_.begin(), acknowledged);
}

int CommandResender::ResendDue(std::int64_t now_us) {
  given_up_.clear();
  for (Pending& p : pending_) {
    if (now_us - p.last_sent_us < policy_.period_us) continue;
    if (p.resends >= policy_.max_resends) {
      given_up_.push_back(p.message);
      continue;
    }
    if (PublishCopy(p.message)) ++counts_.num_resent;
    p.last_sent_us = now_us;
    ++p.resends;
  }
  if (given_up_.empty()) return 0;
  std::erase_if(pending_, [this](const Pending& p) {
    return std::any_of(given_up_.begin(), given_up_.end(),
                       [&](const costume_lcm::command& c) { return c.seq == p.message.seq; });
  });
  counts_.num_given_up += static_cast<std::int64_t>(given_up_.size());
  return static_cast<int>(given_up_.size());
}

}  // namespace costume::bus
