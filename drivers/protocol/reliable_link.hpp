// Reliable, in-order, exactly-once delivery of payloads over an unreliable frame stream
// (docs/protocol.md, "Acknowledgement and retransmission"): Go-Back-N with a window of up to
// kMaxWindow frames in flight, cumulative acknowledgements, an adaptive retransmit timeout
// (srtt + 4 rttvar, at least rto_ns; Karn's rule) with exponential backoff (reset on progress), and fast retransmit when the peer reports a gap
// (a pure ack with kFlagNak, sent when a frame arrives ahead of the expected one, like
// Klipper's NAK; duplicates are acked without it so they never trigger retransmissions). A receiver accepts only the next expected sequence
// number; duplicates, reordered and late frames are dropped and re-acknowledged, so the
// sender's go-back-N retransmission fills the gap.
//
// Written once for host and device: fixed buffers, no heap, time passed in by the caller
// (nanoseconds on the caller's own clock). Owner: one thread.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/protocol/frame.hpp"

namespace feedloop::protocol {

class FrameOutput {
 public:
  virtual ~FrameOutput() = default;
  // One whole frame to put on the wire.
  virtual void write_frame(const uint8_t* frame, size_t n) = 0;
};

class PayloadHandler {
 public:
  virtual ~PayloadHandler() = default;
  // A payload delivered in order, exactly once.
  virtual void on_payload(const uint8_t* payload, size_t n) = 0;
};

struct LinkParams {
  int window = 12;                       // frames in flight (<= kMaxWindow)
  int64_t rto_ns = 25'000'000;           // minimum (and initial) retransmit timeout
  int64_t rto_max_ns = 1'000'000'000;    // backoff limit
  int initial_epoch = 0;                 // 0..15; reset() moves to the next epoch
  int64_t fast_retransmit_gap_ns = 5'000'000;  // minimum time between fast retransmits
};

struct LinkStats {
  uint64_t sent = 0, retransmitted = 0, delivered = 0, duplicates_dropped = 0, out_of_order_dropped = 0,
           acks_sent = 0, resets = 0;
};

class ReliableLink {
 public:
  static constexpr int kMaxWindow = 16;

  void configure(const LinkParams& params, FrameOutput* out, PayloadHandler* in);
  // Forgets everything in flight and starts numbering at 0; the next frame carries kFlagReset so
  // the peer resynchronises (used when a session starts).
  void reset();

  bool can_send() const { return count_ < params_.window; }
  int in_flight() const { return count_; }
  // Queues and transmits a payload; false (nothing sent) when the window is full or n too big.
  bool send(const uint8_t* payload, size_t n, int64_t now_ns);
  // Processes received bytes (any chunking); delivers payloads and sends one ack if needed.
  void on_bytes(const uint8_t* data, size_t n, int64_t now_ns);
  // Retransmits on timeout. Call periodically.
  void poll(int64_t now_ns);
  // Retransmits everything in flight now with the initial timeout (after a reconnect).
  void retransmit_now(int64_t now_ns);

  // Host time (ns) of the last acknowledgement progress, or of the first frame put in flight
  // when none was in flight, or of retransmit_now(): a peer that acknowledges nothing for long
  // while frames are in flight has restarted (lost the link state) or hangs.
  int64_t last_progress_ns() const { return progress_ns_; }

  const LinkStats& stats() const { return stats_; }
  const FrameDecoderStats& decoder_stats() const { return decoder_.stats(); }

 private:
  void on_frame(const FrameView& f, int64_t now_ns);
  void transmit(int slot_index, bool retransmission, int64_t now_ns);
  int64_t base_rto_ns() const;
  void send_ack();

  struct Slot {
    uint16_t seq = 0;
    uint8_t flags = 0;
    bool retransmitted = false;
    int64_t sent_ns = 0;
    size_t len = 0;
    uint8_t payload[kMaxPayload] = {};
  };
  LinkParams params_;
  FrameOutput* out_ = nullptr;
  PayloadHandler* in_ = nullptr;
  FrameDecoder decoder_;
  Slot slots_[kMaxWindow];
  int head_ = 0, count_ = 0;   // ring of unacknowledged frames, oldest at head_
  uint16_t next_seq_ = 0;      // sequence number of the next new frame
  uint16_t expected_ = 0;      // next sequence number expected from the peer
  bool reset_pending_ = false; // next new frame carries kFlagReset
  int epoch_ = 0;              // own link epoch (flags bits 4-7), changes on reset()
  int peer_epoch_ = -1;        // epoch of the peer's last honoured reset
  bool ack_pending_ = false;
  int64_t timer_start_ns_ = 0;
  int64_t progress_ns_ = 0;
  int64_t rto_ns_ = 0;
  bool nak_pending_ = false;   // the next pure ack carries kFlagNak
  double srtt_ns_ = 0.0, rttvar_ns_ = 0.0;  // smoothed round trip and its variation
  int64_t last_fast_ns_ = INT64_MIN / 2;
  uint8_t frame_[kMaxFrame] = {};
  LinkStats stats_;
};

}  // namespace feedloop::protocol
