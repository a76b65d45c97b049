// Clock sync between the session's thread and the I/O thread: see clock_sync_channel.hpp.
#include "drivers/clock_sync_channel.hpp"

namespace feedloop::drivers {

void ClockSyncChannel::configure(const ClockSyncParams& p) {
  ++generation_;
  if (!async_) {
    sync_.configure(p);
    est_ = sync_.estimate();
    return;
  }
  est_ = ClockSync::nominal(p);  // until the I/O thread's first fit
  reset_params_ = p;
  reset_pending_ = true;
  push_reset();
}

// The reset must reach the I/O thread before any sample of its generation (a full queue: the
// I/O thread has not run for seconds; retried with the next sample or refresh).
bool ClockSyncChannel::push_reset() {
  if (!reset_pending_) return true;
  Item it;
  it.reset = true;
  it.generation = generation_;
  it.params = reset_params_;
  if (!pending_.try_push(it)) return false;
  reset_pending_ = false;
  return true;
}

void ClockSyncChannel::add_sample(double send_s, double recv_s, int64_t mcu_clock) {
  if (!async_) {
    sync_.add_sample(send_s, recv_s, mcu_clock);
    est_ = sync_.estimate();
    return;
  }
  if (!push_reset()) {
    ++dropped_;
    return;
  }
  Item it;
  it.generation = generation_;
  it.send_s = send_s;
  it.recv_s = recv_s;
  it.mcu_clock = mcu_clock;
  if (!pending_.try_push(it)) ++dropped_;
}

void ClockSyncChannel::refresh() {
  if (!async_) return;
  push_reset();
  const Published p = published_.load();
  if (p.generation == generation_ && p.estimate.samples() > 0) est_ = p.estimate;
}

void ClockSyncChannel::on_io_thread() {
  Item it;
  bool fitted = false;
  while (pending_.try_pop(it)) {
    if (it.reset) {
      sync_.configure(it.params);  // allocates the window: once per identify, on this thread
      io_generation_ = it.generation;
      continue;
    }
    if (it.generation != io_generation_) continue;  // a sample of the fit before the reset
    sync_.add_sample(it.send_s, it.recv_s, it.mcu_clock);
    fitted = true;
  }
  if (fitted) published_.store({io_generation_, sync_.estimate()});
}

}  // namespace feedloop::drivers
