#include "daemon/watchdog.hpp"

#include <systemd/sd-daemon.h>  // sd_notify, sd_watchdog_enabled

#include <chrono>

namespace feedloop::daemon {

SystemdNotifier::SystemdNotifier(std::function<bool()> healthy) : healthy_(std::move(healthy)) {
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0) watchdog_usec_ = usec;
}

SystemdNotifier::~SystemdNotifier() { stop_watchdog(); }

void SystemdNotifier::ready() { sd_notify(0, "READY=1\nSTATUS=running"); }
void SystemdNotifier::stopping() { sd_notify(0, "STOPPING=1\nSTATUS=stopping"); }
void SystemdNotifier::reloading() { sd_notify(0, "RELOADING=1\nSTATUS=reloading configuration"); }
void SystemdNotifier::status(const std::string& text) {
  sd_notify(0, ("STATUS=" + text).c_str());
}

void SystemdNotifier::start_watchdog() {
  if (watchdog_usec_ == 0 || thread_.joinable()) return;
  stop_ = false;
  thread_ = std::thread([this] {
    // Pet at a quarter of the timeout, only while healthy: a servo loop that stops cycling
    // lets the timeout expire and systemd restarts the service.
    const auto interval = std::chrono::microseconds(watchdog_usec_ / 4);
    while (!stop_.load()) {
      if (healthy_()) {
        sd_notify(0, "WATCHDOG=1");
        pets_.fetch_add(1);
      }
      auto until = std::chrono::steady_clock::now() + interval;
      while (!stop_.load() && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  });
}

void SystemdNotifier::stop_watchdog() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

}  // namespace feedloop::daemon
