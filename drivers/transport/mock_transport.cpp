// Mock transport with fault injection: see mock_transport.hpp.
#include "drivers/transport/mock_transport.hpp"

#include <algorithm>  // std::min
#include <cstring>    // memcpy, memmove

#include "drivers/protocol/frame.hpp"

namespace feedloop::drivers {

namespace {
protocol::FrameFaults line_faults(const MockFaults& f) {
  protocol::FrameFaults l;
  l.drop = f.drop;
  l.corrupt = f.corrupt;
  l.duplicate = f.duplicate;
  l.reorder = f.reorder;
  l.delay = f.delay;
  l.latency_s = f.latency_s;
  l.jitter_s = f.jitter_s;
  l.reorder_extra_s = f.reorder_extra_s;
  l.delay_extra_s = f.delay_extra_s;
  return l;
}
}  // namespace

MockTransport::MockTransport(device::VirtualMcu& mcu, const MockFaults& faults, std::string name)
    : mcu_(mcu), faults_(faults), name_(std::move(name)) {
  to_device_.configure(line_faults(faults), faults.seed);
  to_host_.configure(line_faults(faults), faults.seed * 0x9E3779B97F4A7C15ull + 1);
}

void MockTransport::set_faults(const MockFaults& f) {
  faults_ = f;
  to_device_.set_faults(line_faults(f));
  to_host_.set_faults(line_faults(f));
}

const MockStats& MockTransport::stats() const {
  const auto& a = to_device_.stats();
  const auto& b = to_host_.stats();
  stats_.frames = a.frames + b.frames;
  stats_.dropped = a.dropped + b.dropped;
  stats_.corrupted = a.corrupted + b.corrupted;
  stats_.duplicated = a.duplicated + b.duplicated;
  stats_.reordered = a.reordered + b.reordered;
  stats_.delayed = a.delayed + b.delayed;
  stats_.overflowed = a.overflowed + b.overflowed + rx_overflowed_;
  stats_.lost_unplugged = lost_unplugged_;
  return stats_;
}

Status MockTransport::open() {
  if (!plugged_) return Error{"mock MCU '" + name_ + "' is unplugged", {}};
  open_ = true;
  return {};
}

void MockTransport::unplug() {
  plugged_ = false;
  lost_unplugged_ += static_cast<uint64_t>(to_device_.clear() + to_host_.clear());
  rx_head_ = rx_len_ = 0;
}

Status MockTransport::write(const uint8_t* data, size_t n) {
  if (!connected()) return Error{"mock MCU '" + name_ + "' is disconnected", {}};
  to_device_.send(data, n, now_s_);
  return {};
}

Result<size_t> MockTransport::read(uint8_t* buf, size_t cap) {
  if (!connected()) return Error{"mock MCU '" + name_ + "' is disconnected", {}};
  const size_t n = std::min(cap, rx_len_);
  std::memcpy(buf, rx_ + rx_head_, n);
  rx_head_ += n;
  rx_len_ -= n;
  if (rx_len_ == 0) rx_head_ = 0;
  return n;
}

void MockTransport::append_rx(const uint8_t* data, size_t n) {
  if (rx_len_ + n > kRxBytes) {
    ++rx_overflowed_;  // the host does not read: lost like on a full UART buffer
    return;
  }
  if (rx_head_ + rx_len_ + n > kRxBytes) {
    std::memmove(rx_, rx_ + rx_head_, rx_len_);
    rx_head_ = 0;
  }
  std::memcpy(rx_ + rx_head_ + rx_len_, data, n);
  rx_len_ += n;
}

void MockTransport::collect_device_output(double t_s) {
  uint8_t frame[protocol::kMaxFrame];
  size_t n = 0;
  while (mcu_.pop_frame(frame, n)) {
    if (plugged_) to_host_.send(frame, n, t_s);
    else ++lost_unplugged_;
  }
}

void MockTransport::poll(double now_s, double /*max_wait_s*/) {
  if (now_s < now_s_) now_s = now_s_;
  // Host -> device frames and device activity, interleaved in time order.
  uint8_t f[protocol::kMaxFrame];
  size_t n = 0;
  while (to_device_.next_due() <= now_s) {
    const double t = to_device_.next_due();
    to_device_.pop_due(t, f, n);
    mcu_.run_until(t);
    collect_device_output(t);
    mcu_.receive(f, n, t);
    collect_device_output(t);
  }
  mcu_.run_until(now_s);
  collect_device_output(now_s);
  while (to_host_.pop_due(now_s, f, n)) append_rx(f, n);
  now_s_ = now_s;
}

}  // namespace feedloop::drivers
