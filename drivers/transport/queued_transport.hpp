// The part that serial and USB share: the caller's side of a transport as two bounded lock-free
// SPSC queues, and an I/O thread that moves the bytes (DESIGN.md "Threads and time": every byte to
// or from an MCU moves on an I/O thread, never on a thread whose timing matters).
//
//   caller (servo thread)                          I/O thread (one per transport)
//   try_write(frame) --> [tx: 256 frames] -------> device_io(): write()/libusb_submit_transfer
//   read(bytes)      <-- [rx: 256 chunks of 512] <-- stamped with CLOCK_MONOTONIC as they arrive
//   (clock sync: samples) ----------------------> IoTask::on_io_thread(): the fit, published back
//
// The caller never blocks, never makes a syscall and never allocates in try_write()/read()
// (allocation only on the error paths: error_text(), a failed read()). A full send queue is
// back pressure: try_write() says kFull at once and counts it (the reliable link retransmits the
// frame later, so no step is lost). A full receive queue pauses reading (counted): the bytes wait
// in the kernel or the device. A lost link (write/read error, hang-up, USB NO_DEVICE) turns
// connected() false with error_text() saying why; open() then asks the I/O thread to reopen.
//
// The I/O thread sleeps in ppoll()/libusb event handling for at most io_period_s (500 us), so a
// queued frame leaves within that; received bytes wake it at once. Each frame's departure and
// each chunk's arrival are stamped there (departure_time_s(), last_read_time_s()) so the clock
// sync measures the round trip of the wire, not the queues.
//
// Without an I/O thread (params.io_thread = false) poll() does the device I/O on the caller's
// thread and nothing is stamped: deterministic, for tests in virtual time.
// Owner: the caller's side is one thread (the servo thread); the device side is the I/O thread.
// Derived classes call shutdown() first in their destructor.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <thread>

#include "core/seqlock.hpp"
#include "core/spsc_queue.hpp"
#include "drivers/protocol/frame.hpp"
#include "drivers/transport.hpp"

namespace feedloop::drivers {

struct QueuedTransportParams {
  size_t tx_frames = 255;        // frames waiting for the I/O thread (100 ms at 1 kHz x 2.5)
  size_t rx_chunks = 255;        // received chunks waiting for the caller
  double io_period_s = 500e-6;   // the I/O thread's longest sleep: a queued frame waits at most this
  double open_wait_s = 5.0;      // the first open() waits this long for the I/O thread's attempt
  bool io_thread = true;         // false: poll() does the I/O on the caller's thread (tests)
  // SCHED_FIFO priority of the I/O thread (0: the default policy). It must not be starved while a
  // real-time servo thread fills its queue: the machine gives it the servo's priority - 1. When
  // the system refuses, the thread runs at the default policy and io_stats().io_realtime is false.
  int rt_priority = 0;
  const char* thread_name = "fl-io";  // pthread name (at most 15 characters)
};

class QueuedTransport : public Transport {
 public:
  static constexpr size_t kRxChunkBytes = 512;
  static constexpr size_t kDepartures = 256;  // departure stamps remembered

  ~QueuedTransport() override;
  QueuedTransport(const QueuedTransport&) = delete;
  QueuedTransport& operator=(const QueuedTransport&) = delete;

  // Transport: the caller's side (RT-safe: try_write, read, poll with max_wait_s = 0,
  // connected, last_read_time_s, departure_time_s, tx_ticket, io_stats).
  Status open() final;
  void close() final;
  bool connected() const final { return up_.load(std::memory_order_acquire); }
  Status write(const uint8_t* data, size_t n) final;
  TxResult try_write(const uint8_t* data, size_t n) final;
  Result<size_t> read(uint8_t* buf, size_t cap) final;
  void poll(double now_s, double max_wait_s) final;
  std::string error_text() const final;
  double last_read_time_s() const final;
  uint64_t tx_ticket() const final { return tickets_; }
  double departure_time_s(uint64_t ticket) const final;
  void set_time_base_ns(int64_t epoch_ns) final { epoch_ns_ = epoch_ns; }
  bool run_on_io_thread(IoTask* task) final;
  TransportStats io_stats() const final;

  // The I/O side (every device-side thread) stops for `seconds` from its next turn (a stalled I/O
  // thread: tests, lateness injection). No effect without an I/O thread.
  void pause_io(double seconds);
  bool has_io_thread() const { return params_.io_thread; }
  // CPU time the device-side threads have used (s; 0 without them). Syscalls: for tests and
  // benchmarks.
  virtual double io_thread_cpu_s();

 protected:
  explicit QueuedTransport(const QueuedTransportParams& params);
  // Stops the I/O thread and closes the device.
  void shutdown();

  // ---- Device side: called on the I/O thread (without one: by open()/poll() on the caller's).
  // Opens the device; may block; errors say which device and what to do.
  virtual Status device_open() = 0;
  virtual void device_close() = 0;
  // One turn: send what tx_front() offers, receive into rx_claim()/rx_commit(), wait up to
  // max_wait_s for the device. A lost link: link_failed(why), then return.
  virtual void device_io(double max_wait_s) = 0;

  struct TxFrame {
    uint64_t ticket = 0;
    uint32_t generation = 0;
    uint16_t n = 0;
    uint8_t bytes[protocol::kMaxFrame] = {};
  };
  // The next frame to send (frames queued before the last open() are skipped), nullptr if none.
  const TxFrame* tx_front();
  void tx_pop();
  // Records that frame `ticket` is handed to the device now (call just before the write/submit).
  void tx_departs(uint64_t ticket);
  // Room for one chunk of up to kRxChunkBytes (nullptr and counted when the queue is full).
  uint8_t* rx_claim();
  // Publishes the claimed chunk: n bytes, received at mono_ns (CLOCK_MONOTONIC).
  void rx_commit(size_t n, int64_t mono_ns);
  bool rx_full() const { return rx_.size() >= rx_.capacity(); }
  void note_tx_blocked() { tx_blocked_.fetch_add(1, std::memory_order_relaxed); }
  // The link is lost: connected() turns false, error_text() is `why` (the first reason when two
  // device-side threads fail at once). Allocates (rare).
  void link_failed(const std::string& why);
  static int64_t mono_ns();
  static void sleep_s(double s);
  static double thread_cpu_s(std::thread& t);
  // For a device-side thread of a derived class (serial's writer): the turn bookkeeping the I/O
  // thread does, i.e. sleeps out a pause_io() and records the gap since `last_turn_ns`.
  void begin_turn(int64_t& last_turn_ns);
  bool stopping() const { return stop_.load(std::memory_order_acquire); }
  const QueuedTransportParams& io_params() const { return params_; }

 private:
  struct RxChunk {
    int64_t stamp_ns = 0;
    uint16_t n = 0, taken = 0;
    uint8_t bytes[kRxChunkBytes] = {};
  };
  struct Departure {
    std::atomic<uint64_t> ticket_plus_1{0};
    std::atomic<int64_t> ns{0};
  };
  struct ErrorText {
    char text[240] = {};
  };
  void io_main();
  void io_turn(double max_wait_s);
  void try_device_open();
  void set_error(const std::string& why);

  QueuedTransportParams params_;
  SpscQueue<TxFrame> tx_;
  SpscQueue<RxChunk> rx_;
  std::array<Departure, kDepartures> departures_{};
  std::atomic<bool> up_{false};
  std::atomic<uint32_t> generation_{0};  // bumped by open(): older queued frames are not sent
  Seqlock<ErrorText> error_;

  // Caller's side.
  uint64_t tickets_ = 0;
  int64_t epoch_ns_ = 0;
  int64_t last_read_ns_ = 0;
  bool have_read_stamp_ = false;
  bool waited_first_open_ = false;

  // I/O side.
  bool device_is_open_ = false;

  // Between the two.
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> open_requests_{0}, opens_done_{0};
  std::atomic<int64_t> pause_until_ns_{0};
  std::atomic<bool> failing_{false};  // a device-side thread is taking the link down
  std::atomic<IoTask*> task_{nullptr};
  std::atomic<bool> in_task_{false};
  std::atomic<uint64_t> tx_frames_{0}, tx_full_{0}, tx_blocked_{0}, rx_chunks_{0}, rx_bytes_{0}, rx_queue_full_{0},
      io_errors_{0}, io_turns_{0}, io_pauses_{0};
  std::atomic<int64_t> io_max_gap_ns_{0};
  std::atomic<bool> io_realtime_{false};
};

}  // namespace feedloop::drivers
