// Test helper: an in-process feedloopd on the embedded simulated printer, its sockets in a
// fresh temporary directory, its I/O loop on a background thread.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "config/config.hpp"
#include "daemon/daemon.hpp"

namespace feedloop::testing {

inline std::string make_temp_dir(const std::string& tag) {
  std::string tmpl = (std::filesystem::temp_directory_path() / ("feedloop-" + tag + "-XXXXXX")).string();
  char* p = ::mkdtemp(tmpl.data());
  return p ? std::string(p) : std::string();
}

class DaemonFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("daemon");
    ASSERT_FALSE(dir_.empty());
    ::setenv("RUNTIME_DIRECTORY", dir_.c_str(), 1);  // the sockets belong in the runtime directory
    config::MachineConfig cfg = config::default_config();
    // Most daemon tests send moves without G28; a test of homing itself sets this back to false.
    cfg.planner.allow_moves_before_homing = true;
    cfg.sockets.unix_socket = dir_ + "/feedloop.sock";
    cfg.sockets.api_socket = dir_ + "/api.sock";
    cfg.sockets.pty_link = dir_ + "/ttyFeedloop";
    cfg.servo.realtime_priority = 0;
    cfg.servo.lock_memory = false;
    cfg.recorder.directory = dir_ + "/recordings";  // never the user's state directory
#ifdef FEEDLOOP_SANITIZED
    // These tests check what the daemon answers, not its timing; under the sanitizers on a busy
    // CI machine its threads stall for hundreds of ms, which with the default 100 ms lead ends the
    // print in a (correct) "host stalled" stop. The stall rule itself is tested in
    // engine_lateness_test.
    cfg.stepgen.queue_ahead_ms = 400.0;
#endif
    customize(cfg);
    daemon::DaemonOptions options{"", 0.3};
    options.virtual_time = virtual_time();
    customize_options(options);
    daemon_ = std::make_unique<daemon::Daemon>(cfg, options);
    Status s = daemon_->start();
    ASSERT_TRUE(s.ok()) << s.error().to_string();
    thread_ = std::thread([this] { exit_code_ = daemon_->run(); });
  }
  void TearDown() override {
    if (daemon_) daemon_->request_shutdown("test teardown");
    if (thread_.joinable()) thread_.join();
    daemon_.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  virtual void customize(config::MachineConfig&) {}
  virtual void customize_options(daemon::DaemonOptions&) {}
  virtual bool virtual_time() const { return false; }  // feedloopd --virtual-time

  std::string dir_;
  std::unique_ptr<daemon::Daemon> daemon_;
  std::thread thread_;
  int exit_code_ = -1;
};

}  // namespace feedloop::testing
