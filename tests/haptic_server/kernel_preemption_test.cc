// The kernel's preemption model, from the texts a machine offers, in their order of authority.
#include "haptic_server/kernel_preemption.h"

#include <gtest/gtest.h>

namespace costume::haptics {
namespace {

// This VM's configuration (Linux 6.18, PREEMPT_DYNAMIC built with CONFIG_PREEMPT_NONE).
constexpr const char* kNoneConfig =
    "# CONFIG_PREEMPT_VOLUNTARY is not set\nCONFIG_PREEMPT_NONE=y\n# CONFIG_PREEMPT is not set\n"
    "CONFIG_PREEMPT_DYNAMIC=y\nCONFIG_PREEMPT_COUNT=y\n";

TEST(KernelPreemption, ReadsTheCurrentChoiceOfDebugfsFirst) {
  const KernelPreemption p =
      ParseKernelPreemption("none voluntary (full) lazy\n", "preempt=none", "", kNoneConfig);
  EXPECT_EQ(p.model, "full");
  EXPECT_EQ(p.source, "debugfs");
}

TEST(KernelPreemption, ThenTheCommandLineThenUnameThenTheConfiguration) {
  EXPECT_EQ(ParseKernelPreemption("", "ro quiet preempt=voluntary mitigations=auto\n", "",
                                  kNoneConfig).model,
            "voluntary");
  // "nopreempt=x" is another parameter, not preempt=.
  EXPECT_EQ(ParseKernelPreemption("", "nopreempt=full", "", kNoneConfig).model, "none");
  const KernelPreemption rt = ParseKernelPreemption("", "", "#1 SMP PREEMPT_RT Debian", "");
  EXPECT_EQ(rt.model, "rt");
  EXPECT_EQ(rt.source, "uname");
  const KernelPreemption none = ParseKernelPreemption("", "quiet", "#1 SMP PREEMPT_DYNAMIC", kNoneConfig);
  EXPECT_EQ(none.model, "none");
  EXPECT_EQ(none.source, "config");
  // A commented-out option is not set.
  EXPECT_EQ(ParseKernelPreemption("", "", "", "# CONFIG_PREEMPT=y\nCONFIG_PREEMPT_VOLUNTARY=y\n").model,
            "voluntary");
  EXPECT_EQ(ParseKernelPreemption("", "", "", "CONFIG_PREEMPT=y\n").model, "full");
  EXPECT_EQ(ParseKernelPreemption("", "", "", "").model, "");
}

TEST(KernelPreemption, WarnsOnlyWhereKernelPathsCanHoldTheTick) {
  const std::string none = KernelPreemptionWarning({"none", "config"});
  EXPECT_NE(none.find("'none' (from config)"), std::string::npos) << none;
  EXPECT_NE(none.find("preempt=full"), std::string::npos) << none;
  EXPECT_FALSE(KernelPreemptionWarning({"voluntary", "cmdline"}).empty());
  EXPECT_TRUE(KernelPreemptionWarning({"full", "debugfs"}).empty());
  EXPECT_TRUE(KernelPreemptionWarning({"rt", "uname"}).empty());
  EXPECT_TRUE(KernelPreemptionWarning({}).empty());  // unknown: no claim
}

TEST(KernelPreemption, ReadingThisMachineNeverThrows) {
  const KernelPreemption p = ReadKernelPreemption();
  EXPECT_EQ(p.model.empty(), p.source.empty());
}

}  // namespace
}  // namespace costume::haptics
