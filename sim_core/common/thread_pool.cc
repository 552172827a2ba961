#include "sim_core/common/thread_pool.h"

#include <chrono>
#include <string>

#include "sim_core/common/input_error.h"

namespace costume::sim {

namespace {

// How long an idle worker keeps checking for the next loop before it sleeps. PCG's loops
// follow each other within microseconds; a frame's gap between solves is milliseconds, which
// a worker spends asleep rather than holding the core the haptic loop or the GUI may need.
constexpr auto kSpin = std::chrono::microseconds(200);

}  // namespace

ThreadPool::ThreadPool(int threads) {
  if (threads < 1 || threads > kMaxThreads) {
    throw InputError("threads = " + std::to_string(threads) + " is out of range (allowed: 1 .. " +
                     std::to_string(kMaxThreads) + ")");
  }
  workers_.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mutex_);
    stopping_.store(true);
  }
  wake_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

int ThreadPool::HardwareThreads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : n > static_cast<unsigned>(kMaxThreads) ? kMaxThreads : static_cast<int>(n);
}

void ThreadPool::Dispatch(int count, Call call, void* context) {
  // The ticket is closed here (the last loop closed it), so no worker reads these now.
  const std::uint64_t generation = (ticket_.load() >> 32) + 1;
  call_.store(call);
  context_.store(context);
  count_.store(count);
  completed_.store(0);
  {
    // Under the lock, so that a worker between its last look and its wait cannot miss it.
    std::lock_guard lock(mutex_);
    ticket_.store(generation << 32);
  }
  if (sleepers_.load() > 0) wake_.notify_all();
  RunIndices();
  while (completed_.load() != count) std::this_thread::yield();
  ticket_.store((generation << 32) | kClosed);
}

bool ThreadPool::RunIndices() {
  bool ran = false;
  std::uint64_t ticket = ticket_.load();
  while ((ticket & kClosed) != kClosed) {
    const int index = static_cast<int>(ticket & kClosed);
    // Read before the claim; a successful claim proves the ticket was still open, hence
    // that these were its loop's (the caller closes the ticket before rewriting them).
    const int count = count_.load();
    const Call call = call_.load();
    void* const context = context_.load();
    if (index >= count) return ran;
    if (!ticket_.compare_exchange_weak(ticket, ticket + 1)) continue;  // reloaded `ticket`
    call(context, index);
    completed_.fetch_add(1);
    ran = true;
    ticket = ticket_.load();
  }
  return ran;
}

void ThreadPool::WorkerLoop() {
  const auto has_work = [&] {
    const std::uint64_t ticket = ticket_.load();
    return (ticket & kClosed) != kClosed && static_cast<int>(ticket & kClosed) < count_.load();
  };
  while (!stopping_.load()) {
    if (RunIndices()) continue;
    const auto spin_until = std::chrono::steady_clock::now() + kSpin;
    while (!has_work() && !stopping_.load() && std::chrono::steady_clock::now() < spin_until) {
    }
    if (has_work()) continue;
    std::unique_lock lock(mutex_);
    sleepers_.fetch_add(1);
    wake_.wait(lock, [&] { return stopping_.load() || has_work(); });
    sleepers_.fetch_sub(1);
  }
}

}  // namespace costume::sim
