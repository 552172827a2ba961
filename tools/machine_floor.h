#pragma once
/// @file
/// What the machine itself allows a real-time thread, measured beside the benchmarks that use
/// it (haptic_bench): the hypervisor's steal time from /proc/stat, and the gaps a thread sees
/// when it does nothing but read CLOCK_MONOTONIC in a loop. A thread that never waits can only
/// see a gap between two reads when it lost the CPU (to the kernel, to a higher-priority thread,
/// or to the host stopping the virtual CPU); no program on that CPU runs during such a gap, so
/// the gaps are a floor under what any loop can achieve there.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace costume::tools {

/// The `steal` column of /proc/stat's cpu lines [USER_HZ ticks, sysconf(_SC_CLK_TCK) per s]:
/// time the hypervisor ran something else while this virtual CPU wanted to run.
struct StealTicks {
  /// False when the text had no cpu line with a steal column (not Linux, or a kernel < 2.6.11).
  bool available = false;
  /// All CPUs: the "cpuN" lines added up (ParseStealInto says why not the aggregate "cpu"
  /// line), or the aggregate line where there are none.
  std::int64_t total = 0;
  /// "cpu0", "cpu1", ... in order.
  std::vector<std::int64_t> per_cpu;
};

/// Parses /proc/stat text: cpu lines are "cpuN user nice system idle iowait irq softirq steal
/// ..."; steal is the 8th number. Other lines are ignored. Never throws.
StealTicks ParseStealTicks(std::string_view proc_stat);

/// ParseStealTicks of the file at `path` (unavailable when it cannot be read).
StealTicks ReadStealTicks(const std::string& path = "/proc/stat");

/// `after` − `before`, per CPU (the shorter list's CPUs); unavailable unless both are.
StealTicks StealDelta(const StealTicks& before, const StealTicks& after);

/// `a` + `b` per CPU (to add up the deltas of several intervals); an unavailable side adds 0.
StealTicks StealSum(const StealTicks& a, const StealTicks& b);

/// Writes the steal column of each "cpuN" line of /proc/stat text into `per_cpu` (CPU N at
/// index N, at most `max_cpus`) and the sum of all CPU lines' into `*total`; returns how many
/// CPU lines were read (0: none with a steal column; `*total` is then left). Never allocates:
/// for sampling in a tick. The sum, not the aggregate "cpu" line: the kernel adds that line up
/// in a pass before it prints the CPUs' own, so a tick can show in a CPU's line and not yet in
/// the aggregate, and a period's all-CPU count came out below one CPU's.
int ParseStealInto(std::string_view proc_stat, std::int64_t* per_cpu, int max_cpus,
                   std::int64_t* total);

/// What the kernel accounted to a thread and to its CPU over one long period of a loop: the
/// evidence that tells a stall of the guest (the thread waited on a run queue) from one of
/// the host (the virtual CPU itself did not run, which the guest counts as steal).
struct GapRecord {
  /// The period [ns].
  std::int64_t gap_ns = 0;
  /// The thread's run time over it [ns] (/proc/thread-self/schedstat, first field; with
  /// paravirtual steal accounting, time the host took is not in it). The kernel brings a
  /// running thread's count up to date only at its ticks and switches, so a reading can miss
  /// up to a tick of run time, which the next reading's count then includes; a loop that
  /// sleeps between ticks reads just after a switch.
  std::int64_t exec_ns = 0;
  /// Time it waited runnable on a run queue of this kernel [ns] (second field).
  std::int64_t run_delay_ns = 0;
  /// Steal counted over the period [USER_HZ ticks] for the CPU the thread ran on before it,
  /// and for all CPUs. /proc/stat counts in 10 ms ticks, so one period's count is 0 or 1:
  /// summed over many periods it estimates the stolen time (its expectation is exact).
  std::int64_t steal_ticks_cpu = 0;
  std::int64_t steal_ticks_all = 0;
  /// The same from the period's start to the first tick `settle` [ns] after its end: the
  /// guest adds stolen time to /proc/stat at its next scheduler tick, not when it wakes, so
  /// steal taken during a period shows up in the counter shortly after it.
  std::int64_t steal_ticks_cpu_settled = 0;
  std::int64_t steal_ticks_all_settled = 0;
  /// CPU at the tick before and at the tick after the period (sched_getcpu).
  int cpu_before = -1;
  int cpu_after = -1;
};

/// Samples the calling thread's scheduling statistics and the CPUs' steal at every tick of a
/// loop (two preads, about 9 µs here) and keeps a GapRecord for each period longer than
/// `threshold`. For benchmarks only: it adds that work to each tick. Sample never allocates
/// (records beyond `capacity` are counted, not kept) and reopens its files when called from a
/// new thread (a loop restarted on another thread), without a record across the change.
class GapWitness {
 public:
  /// `settle` [ns]: how long after a long period its steal keeps being counted.
  GapWitness(std::int64_t threshold_ns, std::size_t capacity, std::int64_t settle_ns = 20'000'000);
  ~GapWitness();
  GapWitness(const GapWitness&) = delete;
  GapWitness& operator=(const GapWitness&) = delete;

  /// One tick, `now` [ns, CLOCK_MONOTONIC] its wake-up.
  void Sample(std::int64_t now);
  /// Forget the last sample (the loop paused): the next Sample starts a new run of periods.
  void Break();

  const std::vector<GapRecord>& records() const { return records_; }
  /// Long periods seen, kept or not.
  std::int64_t num_long() const { return num_long_; }
  /// False once a file could not be read (no /proc): nothing is recorded then.
  bool available() const { return available_; }

 private:
  static constexpr int kMaxCpus = 64;
  struct Reading {
    std::int64_t now = 0;
    std::int64_t exec_ns = 0;
    std::int64_t run_delay_ns = 0;
    std::int64_t steal_total = 0;
    std::array<std::int64_t, kMaxCpus> steal{};
    int cpu = -1;
  };
  bool Read(std::int64_t now, Reading* reading);
  void Reopen();
  /// Completes the settled steal of the last record, if it waits, from `current_`.
  void Settle();

  std::int64_t threshold_;
  std::int64_t settle_;
  /// The last record waits for its settled steal until this time [ns] (−1: none waits).
  std::int64_t settle_at_ = -1;
  /// Steal at the start of the period of the record that waits.
  Reading settle_from_;
  std::vector<GapRecord> records_;
  std::int64_t num_long_ = 0;
  bool available_ = true;
  int schedstat_fd_ = -1;
  int stat_fd_ = -1;
  long tid_ = -1;
  bool have_last_ = false;
  Reading last_;
  Reading current_;
  std::array<char, 4096> buffer_{};
};

/// Gaps between consecutive clock reads of a spinning thread.
class ClockGaps {
 public:
  /// Thresholds of the counts [ns]: 10, 50, 100, 500 µs, 1, 2, 5, 10 ms.
  static constexpr std::array<std::int64_t, 8> kThresholds = {
      10'000, 50'000, 100'000, 500'000, 1'000'000, 2'000'000, 5'000'000, 10'000'000};
  /// How many of the longest gaps are kept.
  static constexpr int kNumLongest = 10;

  /// One gap [ns] between two consecutive reads. Never allocates.
  void Add(std::int64_t gap);
  /// Adds another run's gaps (reads, spinning time, counts, longest).
  void Merge(const ClockGaps& other);
  /// Time [ns] covered by the reads (the sum of all gaps).
  void AddSpinTime(std::int64_t ns) { spin_ns_ += ns; }

  std::int64_t num_gaps() const { return num_gaps_; }
  std::int64_t spin_ns() const { return spin_ns_; }
  /// Gaps longer than kThresholds[i].
  std::int64_t num_over(int i) const { return num_over_[i]; }
  /// Gaps longer than `threshold` [ns], which must be one of kThresholds (else −1).
  std::int64_t num_over_threshold(std::int64_t threshold) const;
  /// Summed length [ns] of the gaps longer than 100 µs: time this thread did not run.
  std::int64_t lost_ns() const { return lost_ns_; }
  /// The longest gaps [ns], longest first (fewer while fewer were added).
  std::vector<std::int64_t> longest() const;

 private:
  void InsertLongest(std::int64_t gap);

  std::int64_t num_gaps_ = 0;
  std::int64_t spin_ns_ = 0;
  std::array<std::int64_t, kThresholds.size()> num_over_{};
  std::int64_t lost_ns_ = 0;
  std::array<std::int64_t, kNumLongest> longest_{};  // descending; 0 = empty
};

/// Options of SpinOnTheClock.
struct ClockSpinOptions {
  /// Spinning time to aim for [s] > 0 (sleeps between bursts not counted).
  double seconds = 1.0;
  /// SCHED_FIFO priority of the spinning thread (1..99; <= 0: normal priority).
  int priority = 80;
  /// Spin in bursts of this long [s], with `rest` [s] of sleep after each: a SCHED_FIFO thread
  /// that never sleeps hits the kernel's real-time throttling (sched_rt_runtime_us, 0.95 s of
  /// every 1 s by default), which would show as a 50 ms gap of our own making every second.
  double burst = 0.4;
  double rest = 0.1;
  /// If set, sampled (GapWitness::Sample) every `witness_interval` [s] of spinning, from the
  /// spinning thread: a gap shows as a long period whose run time tells whether this kernel
  /// believed the thread was running all along (then only the host can have taken the time).
  GapWitness* witness = nullptr;
  double witness_interval = 100e-6;
};

/// Result of SpinOnTheClock.
struct ClockSpinResult {
  ClockGaps gaps;
  /// "" when the priority was granted (or not asked), otherwise the refusal's text.
  std::string priority_refusal;
};

/// Runs a thread that reads CLOCK_MONOTONIC in a loop and records the gaps between consecutive
/// reads (the deliberate rests between bursts excluded); returns when it has spun `seconds`.
ClockSpinResult SpinOnTheClock(const ClockSpinOptions& options);

}  // namespace costume::tools
