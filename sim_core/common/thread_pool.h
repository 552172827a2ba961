#pragma once
/// @file
/// A fixed set of worker threads for the step's data-parallel loops (the system's assembly and
/// product, the block-Jacobi preconditioner, PCG's vector updates and dot products, the
/// pyramid's transfers and Galerkin products). The caller's thread works too, so a pool of
/// one thread is plain serial code with no worker at all.
///
/// Determinism: loops are cut into chunks whose size does not depend on the thread count
/// (kChunkParticles particles), each chunk's work is the same whichever thread takes it, and
/// reductions add the chunks' partial sums in chunk order on the caller's thread. A run
/// therefore gives the same bits with 1, 2 or any number of threads.
///
/// Workers spin briefly after a loop before sleeping: a PCG iteration dispatches several
/// loops a few microseconds apart, and waking a sleeping thread costs about as long as a
/// small garment's whole loop. The caller never waits for a worker that has not started: it
/// takes the indices itself, so a core busy with another program slows a loop to one
/// thread's speed, not to the kernel's time slice.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace costume::sim {

class ThreadPool {
 public:
  /// Particles per chunk of a parallel loop over particles (fixed: see the file comment).
  static constexpr int kChunkParticles = 256;

  /// `threads` >= 1 counts the caller's thread; throws InputError outside 1 .. kMaxThreads.
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  /// Most threads a pool may have.
  static constexpr int kMaxThreads = 64;
  /// The machine's hardware threads (at least 1).
  static int HardwareThreads();

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls f(index) once for every index in [0, count), spread over the threads; returns when
  /// all calls have returned. f must not throw. Never allocates.
  template <class F>
  void ForEach(int count, F&& f) {
    if (count <= 0) return;
    if (workers_.empty() || count == 1) {
      for (int i = 0; i < count; ++i) f(i);
      return;
    }
    Dispatch(count, [](void* context, int i) { (*static_cast<F*>(context))(i); }, &f);
  }

  /// Calls f(begin, end) for every chunk [begin, end) of kChunkParticles particles of
  /// [0, num_particles). Never allocates.
  template <class F>
  void ForEachChunk(int num_particles, F&& f) {
    ForEach(NumChunks(num_particles), [&](int c) {
      const int begin = c * kChunkParticles;
      f(begin, begin + kChunkParticles < num_particles ? begin + kChunkParticles : num_particles);
    });
  }

  /// Chunks of a loop over `num_particles` particles.
  static int NumChunks(int num_particles) {
    return (num_particles + kChunkParticles - 1) / kChunkParticles;
  }

 private:
  using Call = void (*)(void*, int);
  void Dispatch(int count, Call call, void* context);
  void WorkerLoop();
  /// Claims and runs indices of the open loop until none is left. Returns whether it ran any.
  bool RunIndices();

  // The loop's ticket: its generation (high 32 bits) and the next index to claim (low 32),
  // or kClosed as the index between loops. An index is claimed by compare-and-swap of the
  // whole ticket, so a worker that wakes late cannot claim an index of a later loop with the
  // call of an earlier one: the caller closes the ticket before it rewrites call_, context_
  // and count_, and a claim that succeeds saw the ticket open, hence those of its own loop.
  static constexpr std::uint64_t kClosed = 0xffffffffu;
  std::atomic<std::uint64_t> ticket_{kClosed};
  std::atomic<Call> call_{nullptr};
  std::atomic<void*> context_{nullptr};
  std::atomic<int> count_{0};
  // Indices of the open loop that have returned. The caller waits for all of them, not for
  // the workers: a worker the kernel has not scheduled (another program on the core) costs
  // nothing, since the caller claims the indices it would have taken.
  std::atomic<int> completed_{0};
  std::atomic<int> sleepers_{0};
  std::atomic<bool> stopping_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<std::thread> workers_;
};

/// Calls f(begin, end) over the kChunkParticles chunks of [0, num_particles): on `pool`'s
/// threads, or in chunk order on this thread when `pool` is null. Never allocates.
template <class F>
void ForEachParticleChunk(ThreadPool* pool, int num_particles, F&& f) {
  if (pool) {
    pool->ForEachChunk(num_particles, f);
    return;
  }
  for (int begin = 0; begin < num_particles; begin += ThreadPool::kChunkParticles) {
    const int end = begin + ThreadPool::kChunkParticles;
    f(begin, end < num_particles ? end : num_particles);
  }
}

/// Σ f(begin, end) over the chunks of [0, num_particles), the chunks' partial sums (kept in
/// `partial`, which must hold NumChunks(num_particles) values) added in chunk order: the
/// same bits with or without `pool`, whatever its thread count. Never allocates.
template <class F>
double SumOverParticleChunks(ThreadPool* pool, int num_particles, std::vector<double>& partial,
                             F&& f) {
  ForEachParticleChunk(pool, num_particles, [&](int begin, int end) {
    partial[begin / ThreadPool::kChunkParticles] = f(begin, end);
  });
  double sum = 0.0;
  for (int c = 0; c < ThreadPool::NumChunks(num_particles); ++c) sum += partial[c];
  return sum;
}

}  // namespace costume::sim
