#pragma once
/// @file
/// The GUI's side of the LCM bus: receiving. BusLink subscribes to what the GUI shows (cloth
/// frames, device states, both processes' status) and re-emits each decoded message as a Qt
/// signal. BusThread runs BusLink::Poll on its own thread, so a slow GUI never stalls LCM and
/// LCM never blocks the GUI: the signals reach GUI-thread receivers queued (Qt's
/// AutoConnection across threads). Sending is CommandSender's job (command_sender.h), from
/// the GUI thread (MessageBus::Publish may be called from any thread).

#include <QObject>
#include <QThread>
#include <atomic>
#include <memory>
#include <string>

#include "bus/message_bus.h"
#include "bus/receive_filter.h"
#include "lcm_types/costume_lcm/cloth_frame.hpp"
#include "lcm_types/costume_lcm/device_state.hpp"
#include "lcm_types/costume_lcm/feedback.hpp"
#include "lcm_types/costume_lcm/status.hpp"

Q_DECLARE_METATYPE(costume_lcm::cloth_frame)
Q_DECLARE_METATYPE(costume_lcm::device_state)
Q_DECLARE_METATYPE(costume_lcm::feedback)
Q_DECLARE_METATYPE(costume_lcm::status)

namespace costume::frontend {

/// Registers the message types with Qt's meta-type system (needed for queued signals).
/// Idempotent; BusLink's constructor calls it.
void RegisterMessageTypes();

/// Subscribes to the GUI's channels on `bus` and emits one signal per accepted message.
/// Subscriptions are made in the constructor; Poll must then be called from one thread only
/// (MessageBus threading rule). Messages are filtered as bus::Subscribe does (malformed,
/// oversized, stale and out-of-order ones are counted and dropped).
class BusLink : public QObject {
  Q_OBJECT

 public:
  /// `bus` must outlive the link.
  explicit BusLink(bus::MessageBus& bus, QObject* parent = nullptr);

  /// Dispatches what has arrived, waiting up to `timeout_ms` [ms] for the first message.
  /// Returns the number dispatched, -1 when the transport failed.
  int Poll(int timeout_ms);

  /// Messages dropped by the filters of every subscription since construction.
  std::int64_t dropped() const;

 signals:
  /// One accepted message of each subscribed channel (bus/channels.h), emitted on the thread
  /// that called Poll.
  void clothChunk(const costume_lcm::cloth_frame& chunk);
  void deviceState(const costume_lcm::device_state& state);
  void feedback(const costume_lcm::feedback& message);
  void simStatus(const costume_lcm::status& status);
  void hapticStatus(const costume_lcm::status& status);

 private:
  bus::MessageBus& bus_;
  std::vector<std::shared_ptr<const bus::ReceiveCounts>> counts_;
};

/// Polls a BusLink on its own thread until stopped (the "LCM thread" of the GUI).
class BusThread : public QThread {
  Q_OBJECT

 public:
  /// `link` must outlive the thread; the thread is stopped and joined in the destructor.
  explicit BusThread(BusLink& link, QObject* parent = nullptr);
  ~BusThread() override;
  /// Asks the loop to end and waits for it (at most one poll period, 50 ms).
  void Stop();

 protected:
  void run() override;

 private:
  BusLink& link_;
  std::atomic<bool> stop_{false};
};

}  // namespace costume::frontend
