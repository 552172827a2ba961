#include "tools/machine_floor.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>
#include <thread>

#include "sim_core/common/monotonic_clock.h"

namespace costume::tools {

namespace {

using sim::kNanosPerSecond;
using sim::MonotonicNs;

/// The steal column of one "cpu..." line, or −1 when it has fewer than 8 numbers.
std::int64_t StealOfLine(std::string_view line) {
  std::istringstream fields{std::string(line)};
  std::string name;
  fields >> name;
  std::int64_t value = 0;
  for (int column = 1; column <= 8; ++column) {
    if (!(fields >> value)) return -1;
  }
  return value;
}

}  // namespace

StealTicks ParseStealTicks(std::string_view proc_stat) {
  StealTicks ticks;
  while (!proc_stat.empty()) {
    const std::size_t end = std::min(proc_stat.find('\n'), proc_stat.size());
    const std::string_view line = proc_stat.substr(0, end);
    proc_stat.remove_prefix(std::min(end + 1, proc_stat.size()));
    if (line.substr(0, 3) != "cpu") continue;
    const std::int64_t steal = StealOfLine(line);
    if (steal < 0) continue;
    if (line.size() > 3 && line[3] == ' ') {
      ticks.total = steal;
      ticks.available = true;
    } else {
      ticks.per_cpu.push_back(steal);
    }
  }
  return ticks;
}

StealTicks ReadStealTicks(const std::string& path) {
  std::ifstream file(path);
  if (!file) return {};
  std::ostringstream text;
  text << file.rdbuf();
  return ParseStealTicks(text.str());
}

StealTicks StealDelta(const StealTicks& before, const StealTicks& after) {
  StealTicks delta;
  if (!before.available || !after.available) return delta;
  delta.available = true;
  delta.total = after.total - before.total;
  const std::size_t n = std::min(before.per_cpu.size(), after.per_cpu.size());
  for (std::size_t i = 0; i < n; ++i) delta.per_cpu.push_back(after.per_cpu[i] - before.per_cpu[i]);
  return delta;
}

StealTicks StealSum(const StealTicks& a, const StealTicks& b) {
  if (!a.available) return b;
  if (!b.available) return a;
  StealTicks sum = a;
  sum.total += b.total;
  sum.per_cpu.resize(std::max(a.per_cpu.size(), b.per_cpu.size()), 0);
  for (std::size_t i = 0; i < b.per_cpu.size(); ++i) sum.per_cpu[i] += b.per_cpu[i];
  return sum;
}

void ClockGaps::Add(std::int64_t gap) {
  ++num_gaps_;
  for (std::size_t i = 0; i < kThresholds.size(); ++i) num_over_[i] += gap > kThresholds[i] ? 1 : 0;
  if (gap > 100'000) lost_ns_ += gap;
  InsertLongest(gap);
}

void ClockGaps::InsertLongest(std::int64_t gap) {
  if (gap <= longest_.back()) return;
  // Into the descending list, dropping the shortest.
  std::size_t i = longest_.size() - 1;
  for (; i > 0 && longest_[i - 1] < gap; --i) longest_[i] = longest_[i - 1];
  longest_[i] = gap;
}

void ClockGaps::Merge(const ClockGaps& other) {
  num_gaps_ += other.num_gaps_;
  spin_ns_ += other.spin_ns_;
  for (std::size_t i = 0; i < num_over_.size(); ++i) num_over_[i] += other.num_over_[i];
  lost_ns_ += other.lost_ns_;
  for (std::int64_t gap : other.longest_) InsertLongest(gap);
}

std::int64_t ClockGaps::num_over_threshold(std::int64_t threshold) const {
  for (std::size_t i = 0; i < kThresholds.size(); ++i) {
    if (kThresholds[i] == threshold) return num_over_[i];
  }
  return -1;
}

std::vector<std::int64_t> ClockGaps::longest() const {
  std::vector<std::int64_t> gaps;
  for (std::int64_t gap : longest_) {
    if (gap > 0) gaps.push_back(gap);
  }
  return gaps;
}

ClockSpinResult SpinOnTheClock(const ClockSpinOptions& options) {
  ClockSpinResult result;
  std::thread spinner([&] {
    if (options.priority > 0) {
      sched_param param{};
      param.sched_priority = options.priority;
      const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
      if (error != 0) result.priority_refusal = std::strerror(error);
    }
    const auto to_ns = [](double s) { return static_cast<std::int64_t>(s * kNanosPerSecond); };
    const std::int64_t total = to_ns(options.seconds);
    const std::int64_t burst = std::max<std::int64_t>(1, to_ns(options.burst));
    ClockGaps& gaps = result.gaps;
    while (gaps.spin_ns() < total) {
      const std::int64_t start = MonotonicNs();
      const std::int64_t end = start + std::min(burst, total - gaps.spin_ns());
      std::int64_t previous = start;
      std::int64_t now = start;
      while (now < end) {
        now = MonotonicNs();
        gaps.Add(now - previous);
        previous = now;
      }
      gaps.AddSpinTime(now - start);
      if (gaps.spin_ns() < total) sim::SleepUntilNs(MonotonicNs() + to_ns(options.rest));
    }
  });
  spinner.join();
  return result;
}

}  // namespace costume::tools
