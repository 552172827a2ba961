// LcmBus: URL checks (traffic stays on the machine unless allowed), raw publish/subscribe
// on memq://, channel names, handler exceptions.
#include <gtest/gtest.h>

#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "bus/lcm_bus.h"
#include "sim_core/common/input_error.h"

namespace costume::bus {
namespace {

using costume::sim::InputError;

// The message of the InputError `url` raises under `reach` ("" when none).
std::string UrlErrorMessage(const std::string& url, Reach reach = Reach::kThisHost) {
  try {
    CheckLcmUrl(url, reach);
  } catch (const InputError& error) {
    return error.what();
  }
  return "";
}

TEST(LcmBus, RefusesTtlAboveZeroByDefault) {
  const std::string message = UrlErrorMessage("udpm://239.255.76.67:7667?ttl=1");
  EXPECT_NE(message.find("ttl = 1"), std::string::npos) << message;
  EXPECT_NE(message.find("[0, 0]"), std::string::npos) << message;
  EXPECT_NE(message.find("udpm://239.255.76.67:7667?ttl=1"), std::string::npos) << message;
  EXPECT_THROW(LcmBus("udpm://239.255.76.67:7667?ttl=1"), InputError);
  EXPECT_THROW(LcmBus("udpm://239.255.76.67:7667?recv_buf_size=1000000&ttl=32"), InputError);
}

TEST(LcmBus, AllowsTtlAboveZeroOnlyWhenAskedFor) {
  const LcmUrl url = CheckLcmUrl("udpm://239.255.76.67:7667?ttl=1", Reach::kNetwork);
  EXPECT_EQ(url.provider, "udpm");
  EXPECT_EQ(url.network, "239.255.76.67:7667");
  EXPECT_EQ(UdpmTtl(url), 1);
}

TEST(LcmBus, AcceptsHostOnlyUrls) {
  EXPECT_EQ(UdpmTtl(CheckLcmUrl("udpm://239.255.76.67:7667?ttl=0", Reach::kThisHost)), 0);
  EXPECT_EQ(UdpmTtl(CheckLcmUrl("udpm://239.255.76.67:7667", Reach::kThisHost)), 0);
  EXPECT_EQ(UdpmTtl(CheckLcmUrl("udpm://", Reach::kThisHost)), 0);
  EXPECT_EQ(CheckLcmUrl("memq://", Reach::kThisHost).provider, "memq");
  EXPECT_EQ(CheckLcmUrl("file:///tmp/x.log?mode=r", Reach::kThisHost).options.at("mode"), "r");
  EXPECT_EQ(CheckLcmUrl("tcpq://localhost:7700", Reach::kThisHost).provider, "tcpq");
  EXPECT_NE(UrlErrorMessage("tcpq://10.0.0.2:7700"), "");
  EXPECT_EQ(UrlErrorMessage("tcpq://10.0.0.2:7700", Reach::kNetwork), "");
}

TEST(LcmBus, RefusesMalformedUrlsNamingTheField) {
  EXPECT_NE(UrlErrorMessage("239.255.76.67:7667").find("provider://"), std::string::npos);
  EXPECT_NE(UrlErrorMessage("udp://239.255.76.67:7667").find("provider \"udp\""),
            std::string::npos);
  EXPECT_NE(UrlErrorMessage("udpm://239.255.76.67:7667?ttl=abc").find("ttl = abc"),
            std::string::npos);
  EXPECT_NE(UrlErrorMessage("udpm://?ttl=-1", Reach::kNetwork).find("[0, 255]"),
            std::string::npos);
  EXPECT_NE(UrlErrorMessage("udpm://?ttl=256", Reach::kNetwork).find("[0, 255]"),
            std::string::npos);
  EXPECT_NE(UrlErrorMessage("udpm://?tll=0").find("unknown udpm option \"tll\""),
            std::string::npos);
  EXPECT_NE(UrlErrorMessage("udpm://?ttl").find("not key=value"), std::string::npos);
  EXPECT_NE(UrlErrorMessage("udpm://?recv_buf_size=0").find("recv_buf_size = 0"),
            std::string::npos);
}

TEST(LcmBus, RefusesAnAddressLcmCannotOpen) {
  // Passes our checks, fails in LCM's own parser (not an IPv4 address).
  EXPECT_THROW(LcmBus("udpm://not.an.address:7667?ttl=0"), InputError);
}

TEST(LcmBus, EmptyUrlResolvesLikeLcm) {
  const char* saved = std::getenv("LCM_DEFAULT_URL");
  const std::string saved_value = saved ? saved : "";
  unsetenv("LCM_DEFAULT_URL");
  EXPECT_EQ(ResolveLcmUrl(""), kDefaultLcmUrl);
  setenv("LCM_DEFAULT_URL", "udpm://239.255.76.67:7667?ttl=1", 1);
  EXPECT_EQ(ResolveLcmUrl(""), "udpm://239.255.76.67:7667?ttl=1");
  // The environment cannot smuggle a ttl > 0 past the default reach.
  EXPECT_THROW(LcmBus(""), InputError);
  EXPECT_EQ(ResolveLcmUrl("memq://"), "memq://");
  if (saved) setenv("LCM_DEFAULT_URL", saved_value.c_str(), 1); else unsetenv("LCM_DEFAULT_URL");
}

TEST(LcmBus, DeliversRawPayloadsOnTheSubscribedChannelOnly) {
  LcmBus bus("memq://");
  std::vector<std::vector<std::uint8_t>> received;
  bus.Subscribe("COSTUME_A", [&](std::span<const std::uint8_t> payload) {
    received.emplace_back(payload.begin(), payload.end());
  });
  const std::vector<std::uint8_t> first = {1, 2, 3};
  const std::vector<std::uint8_t> second = {};
  const std::vector<std::uint8_t> other = {9};
  EXPECT_TRUE(bus.Publish("COSTUME_A", first));
  EXPECT_TRUE(bus.Publish("COSTUME_B", other));     // nobody listens: dropped by memq
  EXPECT_TRUE(bus.Publish("COSTUME_AB", other));    // a prefix match must not deliver
  EXPECT_TRUE(bus.Publish("COSTUME_A", second));
  EXPECT_EQ(bus.HandleSubscriptions(100), 2);
  EXPECT_EQ(bus.HandleSubscriptions(0), 0);
  ASSERT_EQ(received.size(), 2u);
  EXPECT_EQ(received[0], first);
  EXPECT_EQ(received[1], second);
}

TEST(LcmBus, RefusesChannelNamesThatAreNotPlainWords) {
  LcmBus bus("memq://");
  const std::vector<std::uint8_t> payload = {1};
  EXPECT_THROW(bus.Publish("", payload), InputError);
  EXPECT_THROW(bus.Publish("COSTUME.*", payload), InputError);
  EXPECT_THROW(bus.Subscribe("COSTUME_.*", [](std::span<const std::uint8_t>) {}), InputError);
  EXPECT_THROW(bus.Publish(std::string(64, 'A'), payload), InputError);
  EXPECT_TRUE(bus.Publish(std::string(63, 'A'), payload));
}

TEST(LcmBus, HandlerExceptionsReachTheCaller) {
  LcmBus bus("memq://");
  int calls = 0;
  bus.Subscribe("COSTUME_A", [&](std::span<const std::uint8_t>) {
    if (++calls == 1) throw std::runtime_error("handler failed");
  });
  const std::vector<std::uint8_t> payload = {1};
  bus.Publish("COSTUME_A", payload);
  bus.Publish("COSTUME_A", payload);
  EXPECT_THROW(bus.HandleSubscriptions(100), std::runtime_error);
  EXPECT_EQ(calls, 1);
  // The second message is still queued and handled normally.
  EXPECT_EQ(bus.HandleSubscriptions(100), 1);
  EXPECT_EQ(calls, 2);
}

}  // namespace
}  // namespace costume::bus
