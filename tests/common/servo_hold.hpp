// A telemetry tap for virtual-time tests that holds the servo thread, and with it virtual time, at
// a point of the motion until the test thread releases it. A test thread that polls a position
// instead sees the carriage wherever its own scheduling lets it look: virtual time runs free
// meanwhile, as fast as the servo thread simulates. A subclass calls hold_here() from the tap's
// callback whose sample reaches the point. Blocking in a tap is for tests only (a tap's calls are
// the servo thread's, engine/telemetry_tap.hpp).
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>

#include "engine/telemetry_tap.hpp"

namespace feedloop::testing {

class ServoHold : public engine::TelemetryTap {
 public:
  ~ServoHold() override { release(); }
  // True once the servo thread is held (false after timeout_s of wall time).
  bool wait_held(double timeout_s) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [this] { return held_; });
  }
  void release() {
    std::lock_guard lock(mutex_);
    released_ = true;
    cv_.notify_all();
  }

 protected:
  // Servo thread: the first call holds it here until release(); later calls return at once.
  void hold_here() {
    if (passed_) return;
    passed_ = true;
    std::unique_lock lock(mutex_);
    held_ = true;
    cv_.notify_all();
    cv_.wait(lock, [this] { return released_; });
  }

 private:
  bool passed_ = false;  // servo thread
  std::mutex mutex_;
  std::condition_variable cv_;
  bool held_ = false, released_ = false;
};

}  // namespace feedloop::testing
