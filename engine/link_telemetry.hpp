// Per-link telemetry of the machine's MCUs, for the JSON API's status: what the servo thread last
// saw of each link (frames, retransmissions, CRC errors, clock-query round trips, the measured
// clock rate). Trivially copyable: published through a Seqlock, read by any thread.
#pragma once

#include <cstdint>

namespace feedloop::engine {

struct LinkTelemetry {
  char name[32] = {};        // the MCU's name in the config
  char state[16] = {};       // idle, identifying, ready, disconnected, failed
  uint64_t frames_sent = 0;  // data frames put on the link (first transmissions)
  uint64_t retransmitted = 0;
  uint64_t delivered = 0;    // frames received from the MCU, in order
  uint64_t duplicates_dropped = 0, out_of_order_dropped = 0;
  uint64_t crc_errors = 0;   // frames received with a bad CRC
  uint64_t resets = 0;       // link resets (reconnects)
  uint64_t bytes_written = 0;
  int in_flight = 0;         // frames sent and not yet acknowledged
  int clock_samples = 0;     // clock queries in the sync window
  double rtt_last_us = 0.0;  // clock query round trips: the latest, the smallest, and the mean of
  double rtt_min_us = 0.0;   // the sync window
  double rtt_mean_us = 0.0;
  double clock_rate_ppm = 0.0;  // the MCU clock's measured rate against its nominal frequency
  // The transport's queues and I/O thread (serial, USB; 0 for the simulated link).
  uint64_t tx_queue_full = 0;   // frames the send queue refused (back pressure; retransmitted later)
  uint64_t tx_blocked = 0;      // times the device did not take bytes (full UART/pty, USB NAK)
  uint64_t rx_queue_full = 0;   // times reading paused because the servo thread had not taken the bytes
  uint64_t io_errors = 0;       // times the link went down
  bool clock_fit_async = false;  // the clock sync's fit runs on the transport's I/O thread
};

struct LinkTelemetrySet {
  static constexpr int kMaxLinks = 8;  // MCUs shown (a delta has 3-4)
  int count = 0;
  LinkTelemetry links[kMaxLinks];
};

}  // namespace feedloop::engine
