#pragma once
/// @file
/// MessageBus over LCM 1.3.1 (docs/PLATFORM.md "LCM 1.3.1"). LCM traffic stays on this
/// machine unless a caller explicitly allows the network: a UDP multicast URL with ttl > 0
/// is refused by default (DESIGN.md "Processes and messages").

#include <exception>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bus/message_bus.h"

namespace lcm {
class LCM;
}

namespace costume::bus {

/// Where LCM traffic may go.
enum class Reach {
  /// Nothing leaves the machine: udpm with ttl = 0, memq, file, tcpq to localhost.
  kThisHost,
  /// The LAN too: udpm with ttl >= 1 (two hosts, haptic server beside the device), tcpq to
  /// any host. Must be asked for explicitly (a command-line flag of the process).
  kNetwork,
};

/// The URL LCM uses when none is given and LCM_DEFAULT_URL is unset: LCM's own default,
/// with the ttl spelled out.
inline constexpr const char* kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

/// An LCM URL, "provider://network?key=value&key=value", taken apart.
struct LcmUrl {
  std::string provider;                        ///< "udpm", "memq", "file" or "tcpq"
  std::string network;                         ///< e.g. "239.255.76.67:7667"; may be empty
  std::map<std::string, std::string> options;  ///< e.g. {"ttl": "0"}
};

/// The URL LcmBus opens for `url`: `url` itself, or when empty $LCM_DEFAULT_URL, or when
/// that is unset or empty kDefaultLcmUrl (the same rule as LCM, so the checks below see what
/// LCM would open).
std::string ResolveLcmUrl(const std::string& url);

/// Parses and checks `url` (already resolved): a known provider; for udpm, options among
/// ttl (integer in [0, 255]; 0 when absent), recv_buf_size (integer > 0) and transmit_only;
/// a ttl > 0 (or tcpq to a host other than localhost/127.x) only with Reach::kNetwork.
/// Throws costume::sim::InputError naming the URL, the field, its value and the allowed range.
LcmUrl CheckLcmUrl(const std::string& url, Reach reach);

/// The udpm time-to-live of a checked URL [hops]: 0 keeps traffic on this machine, 1 on the
/// LAN. 0 for providers other than udpm.
int UdpmTtl(const LcmUrl& url);

/// MessageBus over one lcm::LCM instance.
class LcmBus final : public MessageBus {
 public:
  /// Opens LCM on ResolveLcmUrl(url) after CheckLcmUrl(url, reach). Throws
  /// costume::sim::InputError for a refused URL, or when LCM cannot open it (bad multicast
  /// address, no multicast route: see PLATFORM.md for `ip route add 224.0.0.0/4 dev lo`).
  explicit LcmBus(const std::string& url = "", Reach reach = Reach::kThisHost);
  ~LcmBus() override;
  LcmBus(const LcmBus&) = delete;
  LcmBus& operator=(const LcmBus&) = delete;

  bool Publish(const std::string& channel, std::span<const std::uint8_t> payload) override;
  void Subscribe(const std::string& channel, Handler handler) override;
  int HandleSubscriptions(int timeout_ms) override;

  /// The URL actually opened (after ResolveLcmUrl).
  const std::string& url() const { return url_; }

 private:
  struct Subscription;
  static void Dispatch(Subscription* subscription, std::span<const std::uint8_t> payload);

  std::string url_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  /// An exception a handler threw inside LCM's C dispatch loop, which it must not cross;
  /// rethrown by HandleSubscriptions once LCM has returned.
  std::exception_ptr handler_error_;
};

}  // namespace costume::bus
