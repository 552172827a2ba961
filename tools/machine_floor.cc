#include "tools/machine_floor.h"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <numeric>
#include <sstream>
#include <thread>

#include "sim_core/common/monotonic_clock.h"

namespace costume::tools {

namespace {

using sim::kNanosPerSecond;
using sim::MonotonicNs;

/// The next unsigned decimal number in `*text` (skipping spaces), consumed; −1 if none.
std::int64_t ParseNumber(std::string_view* text) {
  std::size_t i = 0;
  while (i < text->size() && (*text)[i] == ' ') ++i;
  if (i == text->size() || (*text)[i] < '0' || (*text)[i] > '9') {
    text->remove_prefix(i);
    return -1;
  }
  std::int64_t value = 0;
  for (; i < text->size() && (*text)[i] >= '0' && (*text)[i] <= '9'; ++i) {
    value = value * 10 + ((*text)[i] - '0');
  }
  text->remove_prefix(i);
  return value;
}

/// Calls `take(cpu, steal)` for each "cpu..." line of /proc/stat text that has a steal column
/// (the 8th number): cpu −1 for the aggregate "cpu" line, N for "cpuN". Never allocates.
template <class Take>
void ForEachCpuSteal(std::string_view proc_stat, Take take) {
  while (!proc_stat.empty()) {
    const std::size_t end = std::min(proc_stat.find('\n'), proc_stat.size());
    std::string_view line = proc_stat.substr(0, end);
    proc_stat.remove_prefix(std::min(end + 1, proc_stat.size()));
    if (line.substr(0, 3) != "cpu") continue;
    line.remove_prefix(3);
    int cpu = -1;
    if (!line.empty() && line[0] != ' ') cpu = static_cast<int>(ParseNumber(&line));
    std::int64_t value = -1;
    for (int column = 1; column <= 8; ++column) value = ParseNumber(&line);
    if (value >= 0) take(cpu, value);
  }
}

}  // namespace

StealTicks ParseStealTicks(std::string_view proc_stat) {
  StealTicks ticks;
  ForEachCpuSteal(proc_stat, [&ticks](int cpu, std::int64_t steal) {
    if (cpu < 0) {
      ticks.total = steal;
      ticks.available = true;
    } else {
      ticks.per_cpu.push_back(steal);
    }
  });
  // As ParseStealInto: the CPUs' own lines, read after the aggregate was summed.
  if (!ticks.per_cpu.empty()) {
    ticks.total = std::accumulate(ticks.per_cpu.begin(), ticks.per_cpu.end(), std::int64_t{0});
  }
  return ticks;
}

int ParseStealInto(std::string_view proc_stat, std::int64_t* per_cpu, int max_cpus,
                   std::int64_t* total) {
  int count = 0;
  std::int64_t sum = 0;
  ForEachCpuSteal(proc_stat, [&](int cpu, std::int64_t steal) {
    if (cpu < 0) return;
    sum += steal;
    if (cpu < max_cpus) {
      per_cpu[cpu] = steal;
      ++count;
    }
  });
  if (count > 0) *total = sum;
  return count;
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

GapWitness::GapWitness(std::int64_t threshold_ns, std::size_t capacity, std::int64_t settle_ns)
    : threshold_(threshold_ns), settle_(settle_ns) {
  records_.reserve(capacity);
}

GapWitness::~GapWitness() {
  if (schedstat_fd_ >= 0) ::close(schedstat_fd_);
  if (stat_fd_ >= 0) ::close(stat_fd_);
}

void GapWitness::Break() {
  if (settle_at_ >= 0) Settle();  // with the last sample: the pause is not the period's
  have_last_ = false;
}

void GapWitness::Reopen() {
  Break();
  if (schedstat_fd_ >= 0) ::close(schedstat_fd_);
  if (stat_fd_ < 0) stat_fd_ = ::open("/proc/stat", O_RDONLY | O_CLOEXEC);
  schedstat_fd_ = ::open("/proc/thread-self/schedstat", O_RDONLY | O_CLOEXEC);
  available_ = available_ && schedstat_fd_ >= 0 && stat_fd_ >= 0;
}

bool GapWitness::Read(std::int64_t now, Reading* reading) {
  // The cpu lines come first in /proc/stat; 4 KB hold them for up to 64 CPUs.
  const ssize_t n = ::pread(stat_fd_, buffer_.data(), buffer_.size(), 0);
  if (n <= 0) return false;
  std::string_view stat(buffer_.data(), static_cast<std::size_t>(n));
  stat = stat.substr(0, stat.rfind('\n') + 1);  // whole lines only
  if (ParseStealInto(stat, reading->steal.data(), kMaxCpus, &reading->steal_total) == 0) return false;
  const ssize_t m = ::pread(schedstat_fd_, buffer_.data(), buffer_.size(), 0);
  if (m <= 0) return false;
  std::string_view schedstat(buffer_.data(), static_cast<std::size_t>(m));
  reading->exec_ns = ParseNumber(&schedstat);
  reading->run_delay_ns = ParseNumber(&schedstat);
  reading->now = now;
  reading->cpu = sched_getcpu();
  return reading->exec_ns >= 0 && reading->run_delay_ns >= 0;
}

void GapWitness::Sample(std::int64_t now) {
  if (!available_) return;
  const long tid = ::syscall(SYS_gettid);
  if (tid != tid_) {
    tid_ = tid;
    Reopen();
    if (!available_) return;
  }
  if (!Read(now, &current_)) {
    available_ = false;
    return;
  }
  const bool is_long = have_last_ && current_.now - last_.now > threshold_;
  if (settle_at_ >= 0 && (current_.now >= settle_at_ || is_long)) Settle();
  if (is_long) {
    ++num_long_;
    if (records_.size() < records_.capacity()) {
      GapRecord record;
      record.gap_ns = current_.now - last_.now;
      record.exec_ns = current_.exec_ns - last_.exec_ns;
      record.run_delay_ns = current_.run_delay_ns - last_.run_delay_ns;
      const int cpu = std::clamp(last_.cpu, 0, kMaxCpus - 1);
      record.steal_ticks_cpu = current_.steal[cpu] - last_.steal[cpu];
      record.steal_ticks_all = current_.steal_total - last_.steal_total;
      record.cpu_before = last_.cpu;
      record.cpu_after = current_.cpu;
      records_.push_back(record);
      settle_from_ = last_;
      settle_at_ = current_.now + settle_;
      Settle();  // what is counted already; completed when the settling time has passed
      settle_at_ = current_.now + settle_;
    }
  }
  last_ = current_;
  have_last_ = true;
}

void GapWitness::Settle() {
  GapRecord& record = records_.back();
  const int cpu = std::clamp(settle_from_.cpu, 0, kMaxCpus - 1);
  record.steal_ticks_cpu_settled = current_.steal[cpu] - settle_from_.steal[cpu];
  record.steal_ticks_all_settled = current_.steal_total - settle_from_.steal_total;
  settle_at_ = -1;
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
    GapWitness* witness = options.witness;
    const std::int64_t witness_interval = to_ns(options.witness_interval);
    while (gaps.spin_ns() < total) {
      const std::int64_t start = MonotonicNs();
      const std::int64_t end = start + std::min(burst, total - gaps.spin_ns());
      std::int64_t previous = start;
      std::int64_t now = start;
      std::int64_t next_sample = start;
      while (now < end) {
        now = MonotonicNs();
        gaps.Add(now - previous);
        previous = now;
        if (witness != nullptr && now >= next_sample) {
          witness->Sample(now);
          next_sample = now + witness_interval;
        }
      }
      gaps.AddSpinTime(now - start);
      if (witness != nullptr) witness->Break();  // the rest is no gap
      if (gaps.spin_ns() < total) sim::SleepUntilNs(MonotonicNs() + to_ns(options.rest));
    }
  });
  spinner.join();
  return result;
}

}  // namespace costume::tools
