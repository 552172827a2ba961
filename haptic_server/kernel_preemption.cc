#include "haptic_server/kernel_preemption.h"

#include <sys/utsname.h>
#include <zlib.h>

#include <array>
#include <fstream>
#include <sstream>

namespace costume::haptics {
namespace {

/// The whole file, or "" when it cannot be read.
std::string ReadText(const std::string& path) {
  std::ifstream file(path);
  if (!file) return "";
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

/// A gzip file's text (/proc/config.gz), or "" when it cannot be read.
std::string ReadGzipText(const std::string& path) {
  gzFile file = gzopen(path.c_str(), "rb");
  if (file == nullptr) return "";
  std::string text;
  std::array<char, 16384> buffer{};
  int n = 0;
  while ((n = gzread(file, buffer.data(), static_cast<unsigned>(buffer.size()))) > 0) {
    text.append(buffer.data(), static_cast<std::size_t>(n));
  }
  gzclose(file);
  return text;
}

/// The word in parentheses: "none voluntary (full) lazy" → "full".
std::string Parenthesised(std::string_view text) {
  const std::size_t open = text.find('(');
  const std::size_t close = text.find(')', open);
  if (open == std::string_view::npos || close == std::string_view::npos) return "";
  return std::string(text.substr(open + 1, close - open - 1));
}

/// The value of `preempt=` among the command line's words.
std::string PreemptParameter(std::string_view cmdline) {
  std::size_t at = 0;
  while ((at = cmdline.find("preempt=", at)) != std::string_view::npos) {
    if (at == 0 || cmdline[at - 1] == ' ') {
      const std::size_t start = at + 8;
      const std::size_t end = cmdline.find_first_of(" \n", start);
      return std::string(cmdline.substr(start, end == std::string_view::npos ? end : end - start));
    }
    at += 8;
  }
  return "";
}

bool HasLine(std::string_view config, std::string_view line) {
  std::size_t at = 0;
  while ((at = config.find(line, at)) != std::string_view::npos) {
    const bool starts = at == 0 || config[at - 1] == '\n';
    const std::size_t end = at + line.size();
    const bool ends = end == config.size() || config[end] == '\n';
    if (starts && ends) return true;
    at = end;
  }
  return false;
}

std::string ConfigModel(std::string_view config) {
  if (HasLine(config, "CONFIG_PREEMPT_RT=y")) return "rt";
  if (HasLine(config, "CONFIG_PREEMPT=y")) return "full";
  if (HasLine(config, "CONFIG_PREEMPT_LAZY=y")) return "lazy";
  if (HasLine(config, "CONFIG_PREEMPT_VOLUNTARY=y")) return "voluntary";
  if (HasLine(config, "CONFIG_PREEMPT_NONE=y")) return "none";
  return "";
}

}  // namespace

KernelPreemption ParseKernelPreemption(std::string_view debugfs, std::string_view cmdline,
                                       std::string_view uname_version, std::string_view config) {
  if (std::string model = Parenthesised(debugfs); !model.empty()) return {model, "debugfs"};
  if (std::string model = PreemptParameter(cmdline); !model.empty()) return {model, "cmdline"};
  if (uname_version.find("PREEMPT_RT") != std::string_view::npos) return {"rt", "uname"};
  if (std::string model = ConfigModel(config); !model.empty()) return {model, "config"};
  return {};
}

KernelPreemption ReadKernelPreemption() {
  utsname names{};
  const bool named = uname(&names) == 0;
  std::string config = named ? ReadText(std::string("/boot/config-") + names.release) : "";
  if (config.empty()) config = ReadGzipText("/proc/config.gz");
  return ParseKernelPreemption(ReadText("/sys/kernel/debug/sched/preempt"),
                               ReadText("/proc/cmdline"), named ? names.version : "", config);
}

std::string KernelPreemptionWarning(const KernelPreemption& preemption) {
  if (preemption.model != "none" && preemption.model != "voluntary") return "";
  return "kernel preemption '" + preemption.model + "' (from " + preemption.source +
         "): a woken real-time tick waits until other tasks' kernel work yields, which took "
         "milliseconds on a loaded machine; boot with preempt=full or use a PREEMPT_RT kernel";
}

}  // namespace costume::haptics
