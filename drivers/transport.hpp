// One interface for every link to an MCU (DESIGN.md data flow: usb | serial | mock); the config
// chooses. A transport moves whole frames (the host writes one frame per write()) and bytes back;
// it knows nothing about their content.
//
// The caller's side (McuSession, on the servo/motion thread) never waits: try_write() puts a frame
// into a bounded queue or says why it cannot (full: back pressure, counted; down: the link is
// gone), read() takes what has arrived. Serial and USB move the bytes on their own I/O thread
// (transport/queued_transport.hpp), stamp each chunk they receive and each frame they send with
// the host clock, and run IoTasks (the clock sync's fit) there; the mock runs its virtual MCU
// in-process in the caller's time (deterministic in virtual time).
// Owner: one caller thread (the servo thread, a test, the batch-mode pipeline thread).
#pragma once

#include <cmath>  // NAN
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/result.hpp"

namespace feedloop::drivers {

// Work that a transport with an I/O thread runs there after each of its turns (the clock sync's
// fit, drivers/clock_sync.hpp). Called on the I/O thread only.
class IoTask {
 public:
  virtual ~IoTask() = default;
  virtual void on_io_thread() = 0;
};

enum class TxResult {
  kQueued,   // taken; it leaves on the I/O thread's next turn
  kFull,     // the send queue is full (I/O thread stalled or the device does not read): not taken,
             // counted; the reliable link retransmits it later
  kDown,     // the link is down (connected() is false); error_text() says why
  kTooLong,  // larger than a frame can be (a caller's bug)
};

// Counters of a transport's queues and I/O side (zero for the mock). Read from any thread.
struct TransportStats {
  uint64_t tx_frames = 0;       // frames taken by try_write()/write()
  uint64_t tx_full = 0;         // frames refused because the send queue was full
  uint64_t tx_blocked = 0;      // I/O thread: the device did not take bytes (EAGAIN, full pty/UART)
  uint64_t rx_chunks = 0;       // received chunks handed to the caller
  uint64_t rx_bytes = 0;
  uint64_t rx_queue_full = 0;   // I/O thread: the receive queue was full, reading paused (nothing lost)
  uint64_t io_errors = 0;       // the link went down (read/write/transfer errors, hang-ups)
  uint64_t io_turns = 0;        // I/O thread loop iterations
  uint64_t io_pauses = 0;       // pause_io() requests (tests, lateness injection)
  double io_max_gap_us = 0.0;   // the longest time between two I/O thread turns (a stall; pauses too)
  bool io_realtime = false;     // the I/O thread runs with the SCHED_FIFO priority it asked for
};

class Transport {
 public:
  virtual ~Transport() = default;
  // Opens (or re-opens after a disconnect). Errors say which device and what to do. A transport
  // with an I/O thread waits for the result of its first open; afterwards open() only asks the I/O
  // thread to try again and returns at once (ok when the link is up, else the last error).
  virtual Status open() = 0;
  virtual void close() = 0;
  virtual bool connected() const = 0;
  // Writes one frame (blocking transports) or queues it. An error means the link is down or the
  // queue is full; the message says which. Allocates on error only.
  virtual Status write(const uint8_t* data, size_t n) = 0;
  // Queues one frame without waiting and without allocating. Default: write().
  virtual TxResult try_write(const uint8_t* data, size_t n) { return write(data, n).ok() ? TxResult::kQueued : TxResult::kDown; }
  // Copies up to cap received bytes into buf; 0 when nothing is there. Error: link down.
  virtual Result<size_t> read(uint8_t* buf, size_t cap) = 0;
  // Lets time pass for in-process transports (the mock runs its virtual MCU up to now_s); a
  // transport without an I/O thread does its I/O here; one with an I/O thread does no I/O here and
  // only waits up to max_wait_s for received bytes (never pass a wait on a timing thread).
  virtual void poll(double now_s, double max_wait_s) = 0;
  // "serial /dev/ttyACM0", "usb 1d50:614e serial 1234", "mock x"...
  virtual std::string describe() const = 0;
  // Why the link is down (after kDown). Allocates.
  virtual std::string error_text() const { return describe() + " is down"; }

  // Time stamps (transports with an I/O thread; NaN otherwise: the caller's now is the time).
  // Host time of the bytes the last read() returned: when the I/O thread took them from the
  // device (after their arrival), in seconds on the caller's time line: CLOCK_MONOTONIC minus
  // set_time_base_ns()'s epoch.
  virtual double last_read_time_s() const { return NAN; }
  // Frames taken so far; the frame just taken by try_write() is number tx_ticket() - 1.
  virtual uint64_t tx_ticket() const { return 0; }
  // When frame `ticket` was handed to the device (just before; on the same time line), NaN when not
  // yet sent or no longer remembered (the last 256 frames are).
  virtual double departure_time_s(uint64_t /*ticket*/) const { return NAN; }
  // The caller's time line: its seconds are (CLOCK_MONOTONIC ns - epoch_ns) * 1e-9.
  virtual void set_time_base_ns(int64_t /*epoch_ns*/) {}

  // Runs `task` on the I/O thread after each turn; false (task not taken) when the transport has
  // no I/O thread: the caller then does the work itself. nullptr detaches (waits until the I/O
  // thread no longer uses the previous task).
  virtual bool run_on_io_thread(IoTask* /*task*/) { return false; }
  virtual TransportStats io_stats() const { return {}; }
};

}  // namespace feedloop::drivers
