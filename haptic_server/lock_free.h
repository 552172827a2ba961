#pragma once
/// @file
/// The two lock-free hand-overs the haptic server needs between its threads:
///   - TripleBuffer<T>: a single-slot "latest value" mailbox. One producer publishes whole
///     values (a patch from the I/O thread, a pointer sample from the GUI, a sample from a
///     vendor servo thread); one consumer (the tick) takes the newest. Neither side waits.
///   - SpscQueue<T, N>: a bounded first-in first-out ring from the tick to the I/O thread
///     (outgoing messages), dropping on overflow instead of blocking.
///
/// Why three slots and not two: with a double buffer and an atomic pointer swap, the producer
/// may start refilling the buffer it just handed over while the consumer, which took it one
/// tick earlier, is still reading it. A third slot ("middle") removes the race: the producer
/// owns `back`, the consumer owns `front`, and they only ever trade through `middle` with one
/// atomic exchange each. Neither side allocates, locks or spins.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace costume::haptics {

/// Single-producer single-consumer latest-value mailbox.
/// T must be default-constructible; each slot is reused in place, so a T holding vectors keeps
/// their capacity (fill within capacity and the producer never allocates either).
template <typename T>
class TripleBuffer {
 public:
  TripleBuffer() = default;
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  /// Producer: the slot to fill before Publish(). Owned by the producer until Publish.
  T& back() { return slots_[back_]; }

  /// Producer: makes back() the newest value and hands the producer a free slot.
  /// Never blocks; never allocates.
  void Publish() {
    back_ = middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh),
                             std::memory_order_acq_rel) & kIndexMask;
  }

  /// Consumer: takes the newest published value if there is one. Returns true when front()
  /// changed. Never blocks; never allocates.
  bool Update() {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndexMask;
    return true;
  }

  /// Consumer: the value taken by the last successful Update (a default T before that).
  const T& front() const { return slots_[front_]; }
  /// Consumer: mutable access to its own slot (for caching derived values in place).
  T& mutable_front() { return slots_[front_]; }

  /// Calls f(slot) on all three slots; only before the threads start (e.g. to reserve).
  template <typename F>
  void ForEachSlot(F&& f) {
    for (T& slot : slots_) f(slot);
  }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  std::array<T, 3> slots_{};
  std::uint8_t front_ = 0;                 // consumer-owned
  std::uint8_t back_ = 1;                  // producer-owned
  std::atomic<std::uint8_t> middle_{2};    // shared: index | kFresh
};

/// Single-producer single-consumer bounded queue of trivially copyable T; capacity N - 1
/// (N a power of two). TryPush fails instead of blocking when full.
template <typename T, std::size_t N>
class SpscQueue {
  static_assert(N >= 2 && (N & (N - 1)) == 0, "N must be a power of two");
  static_assert(std::is_trivially_copyable_v<T>, "T is copied by value between threads");

 public:
  /// Producer: appends `value`; returns false (and drops it) when the queue is full.
  /// Never blocks; never allocates.
  bool TryPush(const T& value) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    const std::size_t next = (head + 1) & (N - 1);
    if (next == tail_.load(std::memory_order_acquire)) return false;
    items_[head] = value;
    head_.store(next, std::memory_order_release);
    return true;
  }

  /// Consumer: takes the oldest value; returns false when empty. Never blocks.
  bool TryPop(T& value) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    value = items_[tail];
    tail_.store((tail + 1) & (N - 1), std::memory_order_release);
    return true;
  }

  /// Number of queued items (approximate while the other side runs).
  std::size_t size() const {
    return (head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire)) &
           (N - 1);
  }
  static constexpr std::size_t capacity() { return N - 1; }

 private:
  std::array<T, N> items_{};
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
};

}  // namespace costume::haptics
