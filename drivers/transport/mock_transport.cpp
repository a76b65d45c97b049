// Mock transport with fault injection: see mock_transport.hpp.
#include "drivers/transport/mock_transport.hpp"

#include <algorithm>  // std::min, std::max

#include "drivers/protocol/frame.hpp"

namespace feedloop::drivers {

MockTransport::MockTransport(device::VirtualMcu& mcu, const MockFaults& faults, std::string name)
    : mcu_(mcu), faults_(faults), name_(std::move(name)), rng_(faults.seed) {}

Status MockTransport::open() {
  if (!plugged_) return Error{"mock MCU '" + name_ + "' is unplugged", {}};
  open_ = true;
  return {};
}

void MockTransport::unplug() {
  plugged_ = false;
  stats_.lost_unplugged += to_device_.size() + to_host_.size();
  to_device_.clear();
  to_host_.clear();
  rx_.clear();
}

void MockTransport::schedule(Queue& q, const uint8_t* data, size_t n, double t_s) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ++stats_.frames;
  if (u(rng_) < faults_.drop) {
    ++stats_.dropped;
    return;
  }
  std::vector<uint8_t> f(data, data + n);
  if (u(rng_) < faults_.corrupt && n > 0) {
    f[static_cast<size_t>(u(rng_) * static_cast<double>(n)) % n] ^= static_cast<uint8_t>(1 + (rng_() % 255));
    ++stats_.corrupted;
  }
  // A link is FIFO: latency jitter alone never reorders frames; only the reorder and delay
  // faults hold a frame back so that later ones overtake it.
  double& fifo_t = (&q == &to_device_) ? last_to_device_s_ : last_to_host_s_;
  double t = std::max(t_s + faults_.latency_s + faults_.jitter_s * u(rng_), fifo_t);
  fifo_t = t;
  if (u(rng_) < faults_.reorder) {
    t += faults_.reorder_extra_s;
    ++stats_.reordered;
  }
  if (u(rng_) < faults_.delay) {
    t += faults_.delay_extra_s;
    ++stats_.delayed;
  }
  if (u(rng_) < faults_.duplicate) {
    q.emplace(t + 0.5 * faults_.latency_s + faults_.jitter_s * u(rng_), f);
    ++stats_.duplicated;
  }
  q.emplace(t, std::move(f));
}

Status MockTransport::write(const uint8_t* data, size_t n) {
  if (!connected()) return Error{"mock MCU '" + name_ + "' is disconnected", {}};
  schedule(to_device_, data, n, now_s_);
  return {};
}

Result<size_t> MockTransport::read(uint8_t* buf, size_t cap) {
  if (!connected()) return Error{"mock MCU '" + name_ + "' is disconnected", {}};
  const size_t n = std::min(cap, rx_.size());
  std::copy(rx_.begin(), rx_.begin() + static_cast<std::ptrdiff_t>(n), buf);
  rx_.erase(rx_.begin(), rx_.begin() + static_cast<std::ptrdiff_t>(n));
  return n;
}

void MockTransport::collect_device_output(double t_s) {
  uint8_t frame[protocol::kMaxFrame];
  size_t n = 0;
  while (mcu_.pop_frame(frame, n)) {
    if (plugged_) schedule(to_host_, frame, n, t_s);
    else ++stats_.lost_unplugged;
  }
}

void MockTransport::poll(double now_s, double /*max_wait_s*/) {
  if (now_s < now_s_) now_s = now_s_;
  // Host -> device frames and device activity, interleaved in time order.
  while (!to_device_.empty() && to_device_.begin()->first <= now_s) {
    auto it = to_device_.begin();
    const double t = it->first;
    std::vector<uint8_t> f = std::move(it->second);
    to_device_.erase(it);
    mcu_.run_until(t);
    collect_device_output(t);
    mcu_.receive(f.data(), f.size(), t);
    collect_device_output(t);
  }
  mcu_.run_until(now_s);
  collect_device_output(now_s);
  while (!to_host_.empty() && to_host_.begin()->first <= now_s) {
    auto it = to_host_.begin();
    rx_.insert(rx_.end(), it->second.begin(), it->second.end());
    to_host_.erase(it);
  }
  now_s_ = now_s;
}

}  // namespace feedloop::drivers
