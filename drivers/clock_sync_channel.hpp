// The clock sync of one MCU between the thread that talks to it and the thread that fits
// (DESIGN.md "Threads and time": clock sync off the hot path). The session (servo thread) hands
// each clock query's sample in and reads the latest ClockEstimate; the fit (ClockSync, tens of
// microseconds per sample) runs on the transport's I/O thread when the transport has one:
//
//   servo thread: add_sample() --SPSC (63)--> I/O thread: on_io_thread(): ClockSync::add_sample (fit)
//   servo thread: refresh(), estimate() <--Seqlock<ClockEstimate>--
//
// Without an I/O thread (the mock transport, virtual time) the fit runs inline in add_sample():
// deterministic, as before. configure() (a new MCU identified) resets the fit; estimates of the
// fit before it are ignored (a generation number).
// Owner: the session's thread for configure/add_sample/refresh/estimate; on_io_thread() the I/O
// thread. RT-safe: add_sample() and refresh() (no allocation, no lock, no syscall).
#pragma once

#include <cstdint>

#include "core/seqlock.hpp"
#include "core/spsc_queue.hpp"
#include "drivers/clock_sync.hpp"
#include "drivers/transport.hpp"

namespace feedloop::drivers {

class ClockSyncChannel final : public IoTask {
 public:
  static constexpr size_t kPending = 63;  // samples waiting for the I/O thread (6 s at 10/s)

  ClockSyncChannel() : pending_(kPending) {}
  // true: the fit runs on_io_thread() (the transport took this task); false: inline.
  void set_async(bool async) { async_ = async; }
  bool async() const { return async_; }

  // Session's thread.
  void configure(const ClockSyncParams& p);
  void add_sample(double send_s, double recv_s, int64_t mcu_clock);
  // Takes the I/O thread's latest estimate of the current generation (async; no-op inline).
  void refresh();
  const ClockEstimate& estimate() const { return est_; }
  // Samples not fitted because the I/O thread did not keep up (the queue was full).
  uint64_t samples_dropped() const { return dropped_; }

  // I/O thread.
  void on_io_thread() override;

 private:
  struct Item {
    bool reset = false;
    uint32_t generation = 0;
    ClockSyncParams params;
    double send_s = 0.0, recv_s = 0.0;
    int64_t mcu_clock = 0;
  };
  struct Published {
    uint32_t generation = 0;
    ClockEstimate estimate;
  };
  bool push_reset();

  bool async_ = false;
  uint32_t generation_ = 0;  // session's thread
  bool reset_pending_ = false;
  ClockSyncParams reset_params_;
  ClockEstimate est_;
  uint64_t dropped_ = 0;
  SpscQueue<Item> pending_;
  Seqlock<Published> published_;
  ClockSync sync_;               // async: the I/O thread's; inline: the session's
  uint32_t io_generation_ = 0;   // I/O thread
};

}  // namespace feedloop::drivers
