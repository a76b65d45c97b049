// In-process transport to a VirtualMcu in virtual time, with fault injection per frame in both
// directions (protocol::FaultyFrameLine): drop, corrupt (one byte flipped), duplicate, reorder (a
// frame held back so later ones overtake it), delay (held back beyond the retransmit timeout),
// and unplug/replug. poll(now_s) delivers the frames due up to now to the device in time order,
// runs the device up to now and schedules what it sends back with the link latency.
// Real time: fixed buffers (frame pools and a byte ring), no allocation after construction.
// Owner: the thread that drives the session (tests, batch mode, the servo thread).
#pragma once

#include <cstdint>
#include <string>

#include "drivers/device/virtual_mcu.hpp"
#include "drivers/protocol/frame_faults.hpp"
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
           lost_unplugged = 0, overflowed = 0;
};

class MockTransport final : public Transport {
 public:
  static constexpr int kLineFrames = 256;     // frames on the simulated wire, per direction
  static constexpr size_t kRxBytes = 1 << 16; // bytes arrived at the host, not yet read

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
  void set_faults(const MockFaults& f);
  // Both directions together.
  const MockStats& stats() const;
  device::VirtualMcu& mcu() { return mcu_; }

 private:
  void collect_device_output(double t_s);
  void append_rx(const uint8_t* data, size_t n);

  device::VirtualMcu& mcu_;
  MockFaults faults_;
  std::string name_;
  bool open_ = false, plugged_ = true;
  double now_s_ = 0.0;
  protocol::FaultyFrameLine<kLineFrames> to_device_, to_host_;
  uint8_t rx_[kRxBytes] = {};
  size_t rx_head_ = 0, rx_len_ = 0;
  uint64_t lost_unplugged_ = 0, rx_overflowed_ = 0;
  mutable MockStats stats_;
};

}  // namespace feedloop::drivers
