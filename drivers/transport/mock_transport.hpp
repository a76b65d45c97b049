// In-process transport to a VirtualMcu in virtual time, with fault injection per frame in both
// directions: drop, corrupt (one byte flipped), duplicate, reorder (a frame held back so later
// ones overtake it), delay (held back beyond the retransmit timeout), and unplug/replug.
// poll(now_s) delivers the frames due up to now to the device in time order, runs the device up
// to now and schedules what it sends back with the link latency.
// Owner: the thread that drives the session (tests, batch mode).
#pragma once

#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "drivers/device/virtual_mcu.hpp"
#include "drivers/transport.hpp"

namespace feedloop::drivers {

struct MockFaults {
  double drop = 0.0;       // probability per frame
  double corrupt = 0.0;
  double duplicate = 0.0;
  double reorder = 0.0;
  double delay = 0.0;
  double latency_s = 100e-6;    // one way
  double jitter_s = 0.0;        // uniform extra one-way latency in [0, jitter_s]
  double reorder_extra_s = 2e-3;
  double delay_extra_s = 80e-3;
  uint64_t seed = 1;
};

struct MockStats {
  uint64_t frames = 0, dropped = 0, corrupted = 0, duplicated = 0, reordered = 0, delayed = 0,
           lost_unplugged = 0;
};

class MockTransport final : public Transport {
 public:
  MockTransport(device::VirtualMcu& mcu, const MockFaults& faults, std::string name);

  Status open() override;
  void close() override { open_ = false; }
  bool connected() const override { return open_ && plugged_; }
  Status write(const uint8_t* data, size_t n) override;
  Result<size_t> read(uint8_t* buf, size_t cap) override;
  void poll(double now_s, double max_wait_s) override;
  std::string describe() const override { return "mock " + name_; }

  void unplug();   // frames in flight are lost; reads and writes fail until replug() + open()
  void replug() { plugged_ = true; }
  void set_faults(const MockFaults& f) { faults_ = f; }
  const MockStats& stats() const { return stats_; }
  device::VirtualMcu& mcu() { return mcu_; }

 private:
  using Queue = std::multimap<double, std::vector<uint8_t>>;
  void schedule(Queue& q, const uint8_t* data, size_t n, double t_s);
  void collect_device_output(double t_s);

  device::VirtualMcu& mcu_;
  MockFaults faults_;
  std::string name_;
  std::mt19937_64 rng_;
  bool open_ = false, plugged_ = true;
  double now_s_ = 0.0;
  double last_to_device_s_ = 0.0, last_to_host_s_ = 0.0;  // FIFO delivery times
  Queue to_device_, to_host_;
  std::vector<uint8_t> rx_;  // bytes due at the host, not yet read
  MockStats stats_;
};

}  // namespace feedloop::drivers
