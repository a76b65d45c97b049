// Transport queues and the I/O thread: see queued_transport.hpp.
#include "drivers/transport/queued_transport.hpp"

#include <pthread.h>  // pthread_setname_np, pthread_setschedparam
#include <sched.h>    // SCHED_FIFO
#include <time.h>     // clock_gettime, nanosleep

#include <algorithm>  // std::min
#include <cstdio>     // snprintf
#include <cstring>    // memcpy
#include <exception>

namespace feedloop::drivers {

void QueuedTransport::sleep_s(double s) {
  if (s <= 0.0) return;
  const auto ns = static_cast<long long>(s * 1e9);
  timespec ts{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
  while (::nanosleep(&ts, &ts) != 0) {
  }
}

QueuedTransport::QueuedTransport(const QueuedTransportParams& params)
    : params_(params), tx_(params.tx_frames), rx_(params.rx_chunks) {}

QueuedTransport::~QueuedTransport() {
  // A derived class must have called shutdown(): its device_io() may not run after its members
  // are gone. This only guards against a thread left running.
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

int64_t QueuedTransport::mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void QueuedTransport::set_error(const std::string& why) {
  ErrorText e;
  std::snprintf(e.text, sizeof e.text, "%s", why.c_str());
  error_.store(e);
}

std::string QueuedTransport::error_text() const {
  const ErrorText e = error_.load();
  return e.text[0] != '\0' ? std::string(e.text) : describe() + " is not open";
}

void QueuedTransport::link_failed(const std::string& why) {
  if (!up_.load(std::memory_order_acquire) || failing_.exchange(true)) return;  // one reason, once
  set_error(why);
  io_errors_.fetch_add(1, std::memory_order_relaxed);
  up_.store(false, std::memory_order_release);
}

void QueuedTransport::begin_turn(int64_t& last_turn_ns) {
  const int64_t until = pause_until_ns_.load(std::memory_order_acquire);
  if (until > 0) {
    const int64_t left = until - mono_ns();
    if (left > 0) sleep_s(static_cast<double>(left) * 1e-9);  // counted as a gap, like any stall
  }
  const int64_t now = mono_ns();
  int64_t gap = now - last_turn_ns, seen = io_max_gap_ns_.load(std::memory_order_relaxed);
  while (gap > seen && !io_max_gap_ns_.compare_exchange_weak(seen, gap, std::memory_order_relaxed)) {
  }
  last_turn_ns = now;
}

// ---- Device side ----------------------------------------------------------------------------

void QueuedTransport::try_device_open() {
  if (device_is_open_) {
    device_close();
    device_is_open_ = false;
  }
  Status s = device_open();
  if (s.ok()) {
    device_is_open_ = true;
    error_.store(ErrorText{});
    failing_.store(false);
    up_.store(true, std::memory_order_release);
  } else {
    set_error(s.error().message);
  }
}

void QueuedTransport::io_turn(double max_wait_s) {
  if (up_.load(std::memory_order_acquire)) device_io(max_wait_s);
  if (!up_.load(std::memory_order_acquire) && device_is_open_) {  // lost during this turn
    device_close();
    device_is_open_ = false;
  }
}

void QueuedTransport::io_main() {
  pthread_setname_np(pthread_self(), params_.thread_name);
  if (params_.rt_priority > 0) {  // refused (no CAP_SYS_NICE / LimitRTPRIO): the default policy
    sched_param sp{};
    sp.sched_priority = params_.rt_priority;
    io_realtime_.store(pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0);
  }
  uint64_t served = opens_done_.load();
  int64_t last_turn_ns = mono_ns();
  while (!stop_.load(std::memory_order_acquire)) {
    try {
      begin_turn(last_turn_ns);
      if (const uint64_t want = open_requests_.load(std::memory_order_acquire); want != served) {
        served = want;
        if (!up_.load(std::memory_order_acquire)) try_device_open();
        opens_done_.store(served, std::memory_order_release);
      }
      if (up_.load(std::memory_order_acquire)) io_turn(params_.io_period_s);
      else sleep_s(params_.io_period_s);
      // Dekker with run_on_io_thread(nullptr): in_task_ is raised before the task is read.
      in_task_.store(true);
      if (IoTask* t = task_.load()) t->on_io_thread();
      in_task_.store(false);
    } catch (const std::exception& e) {  // nothing may escape a thread
      in_task_.store(false);
      link_failed(describe() + ": I/O thread error: " + e.what());
    }
    io_turns_.fetch_add(1, std::memory_order_relaxed);
  }
  if (device_is_open_) {
    device_close();
    device_is_open_ = false;
  }
}

const QueuedTransport::TxFrame* QueuedTransport::tx_front() {
  const uint32_t gen = generation_.load(std::memory_order_acquire);
  for (;;) {
    const TxFrame* f = tx_.front();
    if (f == nullptr || f->generation == gen) return f;
    tx_.pop();  // queued before the last open(): for a link that is gone
  }
}

void QueuedTransport::tx_pop() { tx_.pop(); }

void QueuedTransport::tx_departs(uint64_t ticket) {
  if (!params_.io_thread) return;
  Departure& d = departures_[ticket % kDepartures];
  d.ticket_plus_1.store(0, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  d.ns.store(mono_ns(), std::memory_order_relaxed);
  d.ticket_plus_1.store(ticket + 1, std::memory_order_release);
}

uint8_t* QueuedTransport::rx_claim() {
  RxChunk* c = rx_.try_claim();
  if (c == nullptr) {
    rx_queue_full_.fetch_add(1, std::memory_order_relaxed);
    return nullptr;
  }
  return c->bytes;
}

void QueuedTransport::rx_commit(size_t n, int64_t stamp_ns) {
  RxChunk* c = rx_.try_claim();  // the slot rx_claim() returned (the producer is this thread)
  if (c == nullptr || n == 0) return;
  c->n = static_cast<uint16_t>(std::min(n, kRxChunkBytes));
  c->taken = 0;
  c->stamp_ns = stamp_ns;
  rx_.commit();
}

// ---- Caller's side --------------------------------------------------------------------------

Status QueuedTransport::open() {
  // Frames queued for the previous link are not sent, bytes received on it not delivered.
  generation_.fetch_add(1, std::memory_order_acq_rel);
  while (rx_.front() != nullptr) rx_.pop();
  have_read_stamp_ = false;
  if (!params_.io_thread) {
    if (!up_.load()) try_device_open();
    return up_.load() ? Status::Ok() : Status(Error{error_text(), {}});
  }
  if (!thread_.joinable()) {
    stop_.store(false);
    thread_ = std::thread([this] { io_main(); });  // startup: may allocate
  }
  if (up_.load(std::memory_order_acquire)) return Status::Ok();
  const uint64_t want = open_requests_.fetch_add(1, std::memory_order_acq_rel) + 1;
  if (!waited_first_open_) {
    // The first open waits for the attempt, so that a missing device is a clear error at startup.
    waited_first_open_ = true;
    const int64_t end = mono_ns() + static_cast<int64_t>(params_.open_wait_s * 1e9);
    while (opens_done_.load(std::memory_order_acquire) < want && mono_ns() < end) sleep_s(200e-6);
    if (opens_done_.load(std::memory_order_acquire) < want)
      return Error{describe() + ": not opened within " + std::to_string(params_.open_wait_s) +
                       " s (the I/O thread is still trying)",
                   {}};
  }
  return up_.load(std::memory_order_acquire) ? Status::Ok() : Status(Error{error_text(), {}});
}

void QueuedTransport::shutdown() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();  // the thread closes the device on its way out
  if (device_is_open_) {
    device_close();
    device_is_open_ = false;
  }
  up_.store(false, std::memory_order_release);
  waited_first_open_ = false;
}

void QueuedTransport::close() { shutdown(); }

TxResult QueuedTransport::try_write(const uint8_t* data, size_t n) {
  if (n > protocol::kMaxFrame) return TxResult::kTooLong;
  if (!up_.load(std::memory_order_acquire)) return TxResult::kDown;
  TxFrame* f = tx_.try_claim();
  if (f == nullptr) {
    tx_full_.fetch_add(1, std::memory_order_relaxed);
    return TxResult::kFull;
  }
  f->ticket = tickets_++;
  f->generation = generation_.load(std::memory_order_relaxed);
  f->n = static_cast<uint16_t>(n);
  std::memcpy(f->bytes, data, n);
  tx_.commit();
  tx_frames_.fetch_add(1, std::memory_order_relaxed);
  return TxResult::kQueued;
}

Status QueuedTransport::write(const uint8_t* data, size_t n) {
  switch (try_write(data, n)) {
    case TxResult::kQueued: return Status::Ok();
    case TxResult::kFull:
      return Error{describe() + ": send queue full (" + std::to_string(tx_.capacity()) +
                       " frames wait: the I/O thread is stalled or the device does not read)",
                   {}};
    case TxResult::kTooLong:
      return Error{describe() + ": a frame of " + std::to_string(n) + " bytes (at most " +
                       std::to_string(protocol::kMaxFrame) + ")",
                   {}};
    case TxResult::kDown: break;
  }
  return Error{error_text(), {}};
}

Result<size_t> QueuedTransport::read(uint8_t* buf, size_t cap) {
  RxChunk* c = rx_.front_mut();
  if (c == nullptr) {
    if (!up_.load(std::memory_order_acquire)) return Error{error_text(), {}};
    return size_t{0};
  }
  const size_t n = std::min(cap, static_cast<size_t>(c->n - c->taken));
  std::memcpy(buf, c->bytes + c->taken, n);
  c->taken = static_cast<uint16_t>(c->taken + n);
  last_read_ns_ = c->stamp_ns;
  have_read_stamp_ = params_.io_thread;
  rx_bytes_.fetch_add(n, std::memory_order_relaxed);
  if (c->taken >= c->n) {
    rx_.pop();
    rx_chunks_.fetch_add(1, std::memory_order_relaxed);
  }
  return n;
}

double QueuedTransport::last_read_time_s() const {
  if (!have_read_stamp_) return NAN;
  return static_cast<double>(last_read_ns_ - epoch_ns_) * 1e-9;
}

double QueuedTransport::departure_time_s(uint64_t ticket) const {
  if (!params_.io_thread) return NAN;
  const Departure& d = departures_[ticket % kDepartures];
  const uint64_t a = d.ticket_plus_1.load(std::memory_order_acquire);
  if (a != ticket + 1) return NAN;
  const int64_t ns = d.ns.load(std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_acquire);
  if (d.ticket_plus_1.load(std::memory_order_relaxed) != a) return NAN;
  return static_cast<double>(ns - epoch_ns_) * 1e-9;
}

void QueuedTransport::poll(double /*now_s*/, double max_wait_s) {
  if (!params_.io_thread) {
    io_turn(max_wait_s);
    return;
  }
  // Nothing to do here: the I/O thread moves the bytes. Test loops may wait for input.
  if (!(max_wait_s > 0.0)) return;
  const int64_t end = mono_ns() + static_cast<int64_t>(max_wait_s * 1e9);
  while (rx_.front() == nullptr && up_.load(std::memory_order_acquire)) {
    const int64_t left = end - mono_ns();
    if (left <= 0) break;
    sleep_s(std::min(100e-6, static_cast<double>(left) * 1e-9));
  }
}

bool QueuedTransport::run_on_io_thread(IoTask* task) {
  if (!params_.io_thread) return false;
  task_.store(task);
  if (task == nullptr) {
    while (in_task_.load()) sleep_s(50e-6);
  }
  return true;
}

double QueuedTransport::io_thread_cpu_s() { return thread_cpu_s(thread_); }

double QueuedTransport::thread_cpu_s(std::thread& t) {
  if (!t.joinable()) return 0.0;
  clockid_t cid{};
  if (pthread_getcpuclockid(t.native_handle(), &cid) != 0) return 0.0;
  timespec ts{};
  if (clock_gettime(cid, &ts) != 0) return 0.0;
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void QueuedTransport::pause_io(double seconds) {
  if (!(seconds > 0.0) || !params_.io_thread) return;
  pause_until_ns_.store(mono_ns() + static_cast<int64_t>(seconds * 1e9), std::memory_order_release);
  io_pauses_.fetch_add(1, std::memory_order_relaxed);
}

TransportStats QueuedTransport::io_stats() const {
  TransportStats s;
  s.tx_frames = tx_frames_.load(std::memory_order_relaxed);
  s.tx_full = tx_full_.load(std::memory_order_relaxed);
  s.tx_blocked = tx_blocked_.load(std::memory_order_relaxed);
  s.rx_chunks = rx_chunks_.load(std::memory_order_relaxed);
  s.rx_bytes = rx_bytes_.load(std::memory_order_relaxed);
  s.rx_queue_full = rx_queue_full_.load(std::memory_order_relaxed);
  s.io_errors = io_errors_.load(std::memory_order_relaxed);
  s.io_turns = io_turns_.load(std::memory_order_relaxed);
  s.io_pauses = io_pauses_.load(std::memory_order_relaxed);
  s.io_max_gap_us = static_cast<double>(io_max_gap_ns_.load(std::memory_order_relaxed)) * 1e-3;
  s.io_realtime = io_realtime_.load(std::memory_order_relaxed);
  return s;
}

}  // namespace feedloop::drivers
