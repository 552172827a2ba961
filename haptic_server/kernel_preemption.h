#pragma once
/// @file
/// The kernel's preemption model, which bounds how late a woken real-time thread can run.
/// Under "none" or "voluntary" a SCHED_FIFO thread woken on time still waits until the task
/// on its CPU leaves a long kernel path (measured here: 2.6 and 5.5 ms, docs/processes.md
/// "Where the gaps come from"); "full", "lazy" and PREEMPT_RT preempt such paths.

#include <string>
#include <string_view>

namespace costume::haptics {

struct KernelPreemption {
  /// "none", "voluntary", "full", "lazy", "rt", or "" when nothing told.
  std::string model;
  /// Where it was read: "debugfs", "cmdline", "uname", "config".
  std::string source;
};

/// The model from, in this order of authority: the current choice in
/// /sys/kernel/debug/sched/preempt (the one in parentheses, e.g. "none voluntary (full)
/// lazy"), a `preempt=` on the kernel command line, "PREEMPT_RT" in `uname -v`, and the
/// kernel configuration's CONFIG_PREEMPT_RT / CONFIG_PREEMPT / CONFIG_PREEMPT_LAZY /
/// CONFIG_PREEMPT_VOLUNTARY / CONFIG_PREEMPT_NONE (=y). Empty texts are skipped.
KernelPreemption ParseKernelPreemption(std::string_view debugfs, std::string_view cmdline,
                                       std::string_view uname_version, std::string_view config);

/// ParseKernelPreemption of this machine's files (/sys/kernel/debug/sched/preempt,
/// /proc/cmdline, uname, /boot/config-<release> or /proc/config.gz); unreadable ones are
/// skipped. Never throws.
KernelPreemption ReadKernelPreemption();

/// A warning for the real-time status when the model lets kernel paths delay the tick
/// ("none", "voluntary"), naming the model, its source and the remedy; "" otherwise.
std::string KernelPreemptionWarning(const KernelPreemption& preemption);

}  // namespace costume::haptics
