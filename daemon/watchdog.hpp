// systemd integration: READY/STOPPING/STATUS notifications and the watchdog. The watchdog
// thread pets systemd (WATCHDOG=1) only while the servo loop is healthy, so a stalled servo
// thread gets the service restarted. Without systemd (no NOTIFY_SOCKET) everything is a no-op.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <thread>

namespace feedloop::daemon {

class SystemdNotifier {
 public:
  // `healthy` is polled from the watchdog thread; it must be thread-safe.
  explicit SystemdNotifier(std::function<bool()> healthy);
  ~SystemdNotifier();

  void ready();
  void stopping();
  void reloading();
  void status(const std::string& text);
  // Starts the watchdog thread when the service has WatchdogSec set (WATCHDOG_USEC).
  void start_watchdog();
  void stop_watchdog();
  bool watchdog_enabled() const { return watchdog_usec_ != 0; }
  uint64_t pets() const { return pets_.load(); }

 private:
  std::function<bool()> healthy_;
  uint64_t watchdog_usec_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> pets_{0};
  std::thread thread_;
};

}  // namespace feedloop::daemon
