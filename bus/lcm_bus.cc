#include "bus/lcm_bus.h"

#include <lcm/lcm-cpp.hpp>

#include <charconv>
#include <cstdlib>
#include <set>
#include <utility>

#include "sim_core/common/input_error.h"

namespace costume::bus {

using costume::sim::InputError;

void RequireValidChannel(const std::string& channel) {
  bool valid = !channel.empty() && static_cast<int>(channel.size()) <= kMaxChannelLength;
  for (char c : channel) {
    const bool word = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                      (c >= '0' && c <= '9') || c == '_';
    valid = valid && word;
  }
  if (!valid) {
    throw InputError("LCM channel \"" + channel + "\" is not allowed: 1 to " +
                     std::to_string(kMaxChannelLength) + " characters from [A-Za-z0-9_]");
  }
}

std::string ResolveLcmUrl(const std::string& url) {
  if (!url.empty()) return url;
  const char* from_environment = std::getenv("LCM_DEFAULT_URL");
  if (from_environment != nullptr && *from_environment != '\0') return from_environment;
  return kDefaultLcmUrl;
}

namespace {

std::string UrlError(const std::string& url, const std::string& detail) {
  return "LCM URL \"" + url + "\": " + detail;
}

// Parses a whole decimal integer into `value`; false when `text` is anything else.
bool ParseInt(const std::string& text, long& value) {
  const char* end = text.data() + text.size();
  auto result = std::from_chars(text.data(), end, value);
  return !text.empty() && result.ec == std::errc() && result.ptr == end;
}

LcmUrl SplitUrl(const std::string& url) {
  const auto scheme_end = url.find("://");
  if (scheme_end == std::string::npos || scheme_end == 0) {
    throw InputError(UrlError(url, "expected provider://network?key=value, e.g. " +
                                       std::string(kDefaultLcmUrl)));
  }
  LcmUrl parsed;
  parsed.provider = url.substr(0, scheme_end);
  const std::string rest = url.substr(scheme_end + 3);
  const auto query = rest.find('?');
  parsed.network = rest.substr(0, query);
  if (query == std::string::npos) return parsed;
  std::string options = rest.substr(query + 1);
  while (!options.empty()) {
    const auto amp = options.find('&');
    const std::string pair = options.substr(0, amp);
    const auto eq = pair.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw InputError(UrlError(url, "option \"" + pair + "\" is not key=value"));
    }
    parsed.options[pair.substr(0, eq)] = pair.substr(eq + 1);
    options = amp == std::string::npos ? "" : options.substr(amp + 1);
  }
  return parsed;
}

void CheckUdpmOptions(const std::string& url, const LcmUrl& parsed, Reach reach) {
  for (const auto& [key, value] : parsed.options) {
    long number = 0;
    if (key == "ttl") {
      if (!ParseInt(value, number) || number < 0 || number > 255) {
        throw InputError(UrlError(url, "ttl = " + value + ": allowed range [0, 255]"));
      }
      if (number > 0 && reach == Reach::kThisHost) {
        throw InputError(UrlError(
            url, "ttl = " + value + ": allowed range [0, 0] unless the network is allowed "
                 "explicitly (--allow-network): with ttl > 0 LCM traffic leaves this machine"));
      }
    } else if (key == "recv_buf_size") {
      if (!ParseInt(value, number) || number <= 0) {
        throw InputError(UrlError(url, "recv_buf_size = " + value + ": allowed range > 0 [bytes]"));
      }
    } else if (key != "transmit_only") {
      throw InputError(UrlError(url, "unknown udpm option \"" + key +
                                         "\": allowed ttl, recv_buf_size, transmit_only"));
    }
  }
}

bool IsLocalHost(const std::string& network) {
  const std::string host = network.substr(0, network.find(':'));
  return host == "localhost" || host.rfind("127.", 0) == 0;
}

}  // namespace

LcmUrl CheckLcmUrl(const std::string& url, Reach reach) {
  LcmUrl parsed = SplitUrl(url);
  static const std::set<std::string> kProviders = {"udpm", "memq", "file", "tcpq"};
  if (kProviders.count(parsed.provider) == 0) {
    throw InputError(UrlError(url, "provider \"" + parsed.provider +
                                       "\" is unknown: allowed udpm, memq, file, tcpq"));
  }
  if (parsed.provider == "udpm") CheckUdpmOptions(url, parsed, reach);
  if (parsed.provider == "tcpq" && reach == Reach::kThisHost && !IsLocalHost(parsed.network)) {
    throw InputError(UrlError(url, "tcpq host \"" + parsed.network +
                                       "\": allowed localhost or 127.x unless the network is "
                                       "allowed explicitly (--allow-network)"));
  }
  return parsed;
}

int UdpmTtl(const LcmUrl& url) {
  const auto ttl = url.options.find("ttl");
  if (url.provider != "udpm" || ttl == url.options.end()) return 0;
  return std::atoi(ttl->second.c_str());
}

struct LcmBus::Subscription {
  LcmBus* bus;
  Handler handler;
};

LcmBus::LcmBus(const std::string& url, Reach reach) : url_(ResolveLcmUrl(url)) {
  CheckLcmUrl(url_, reach);
  lcm_ = std::make_unique<lcm::LCM>(url_);
  if (!lcm_->good()) {
    throw InputError(UrlError(url_, "LCM could not open it (its own message is printed above); "
                                    "for udpm check the multicast address and that a route "
                                    "to 224.0.0.0/4 exists (ip route)"));
  }
}

LcmBus::~LcmBus() = default;

bool LcmBus::Publish(const std::string& channel, std::span<const std::uint8_t> payload) {
  RequireValidChannel(channel);
  return lcm_->publish(channel, payload.data(), static_cast<unsigned int>(payload.size())) == 0;
}

void LcmBus::Subscribe(const std::string& channel, Handler handler) {
  RequireValidChannel(channel);
  subscriptions_.push_back(std::make_unique<Subscription>(Subscription{this, std::move(handler)}));
  lcm_->subscribeFunction(
      channel,
      +[](const lcm::ReceiveBuffer* buffer, const std::string&, Subscription* subscription) {
        Dispatch(subscription, {static_cast<const std::uint8_t*>(buffer->data), buffer->data_size});
      },
      subscriptions_.back().get());
}

void LcmBus::Dispatch(Subscription* subscription, std::span<const std::uint8_t> payload) {
  // LCM calls us from C: an exception must not unwind through it.
  LcmBus& bus = *subscription->bus;
  if (bus.handler_error_) return;  // a previous handler failed: stop dispatching this round
  try {
    subscription->handler(payload);
  } catch (...) {
    bus.handler_error_ = std::current_exception();
  }
}

int LcmBus::HandleSubscriptions(int timeout_ms) {
  int dispatched = 0;
  int status = lcm_->handleTimeout(timeout_ms > 0 ? timeout_ms : 0);
  while (status > 0) {
    ++dispatched;
    if (handler_error_) break;
    status = lcm_->handleTimeout(0);
  }
  if (handler_error_) std::rethrow_exception(std::exchange(handler_error_, nullptr));
  return status < 0 ? -1 : dispatched;
}

}  // namespace costume::bus
