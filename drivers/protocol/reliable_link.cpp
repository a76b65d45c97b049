// Go-Back-N link: see reliable_link.hpp.
#include "drivers/protocol/reliable_link.hpp"

#include <algorithm>  // std::clamp
#include <cmath>      // fabs

namespace feedloop::protocol {

void ReliableLink::configure(const LinkParams& params, FrameOutput* out, PayloadHandler* in) {
  params_ = params;
  if (params_.window < 1) params_.window = 1;
  if (params_.window > kMaxWindow) params_.window = kMaxWindow;
  out_ = out;
  in_ = in;
  head_ = count_ = 0;
  next_seq_ = expected_ = 0;
  rto_ns_ = params_.rto_ns;
  epoch_ = params_.initial_epoch & 0x0F;
  peer_epoch_ = -1;
  reset_pending_ = false;
  ack_pending_ = false;
  decoder_.clear();
}

void ReliableLink::reset() {
  head_ = count_ = 0;
  next_seq_ = 0;
  // The receive side restarts too: a peer that rebooted numbers from 0 without a reset of its
  // own (it had nothing to forget), and a peer that did not resets on our kFlagReset, whatever
  // its epoch (each new session honours the peer's reset once).
  expected_ = 0;
  peer_epoch_ = -1;
  nak_pending_ = false;
  reset_pending_ = true;
  epoch_ = (epoch_ + 1) & 0x0F;
  rto_ns_ = params_.rto_ns;
  ++stats_.resets;
}

bool ReliableLink::send(const uint8_t* payload, size_t n, int64_t now_ns) {
  if (!can_send() || n > kMaxPayload) return false;
  const int idx = (head_ + count_) % kMaxWindow;
  Slot& s = slots_[idx];
  s.seq = next_seq_++;
  s.flags = static_cast<uint8_t>(kFlagData | (epoch_ << 4));
  if (reset_pending_) {
    s.flags |= kFlagReset;
    reset_pending_ = false;
  }
  s.len = n;
  for (size_t i = 0; i < n; ++i) s.payload[i] = payload[i];
  if (count_ == 0) timer_start_ns_ = progress_ns_ = now_ns;
  ++count_;
  transmit(idx, false, now_ns);
  return true;
}

int64_t ReliableLink::base_rto_ns() const {
  if (srtt_ns_ <= 0.0) return params_.rto_ns;
  const auto r = static_cast<int64_t>(srtt_ns_ + 4.0 * rttvar_ns_);
  return std::clamp(r, params_.rto_ns, params_.rto_max_ns);
}

void ReliableLink::transmit(int idx, bool retransmission, int64_t now_ns) {
  Slot& s = slots_[idx];
  s.sent_ns = now_ns;
  s.retransmitted = retransmission;
  const size_t n = encode_frame(frame_, s.flags, s.seq, expected_, s.payload, s.len);
  ack_pending_ = false;  // the frame carries our ack
  if (retransmission) ++stats_.retransmitted; else ++stats_.sent;
  if (out_ != nullptr) out_->write_frame(frame_, n);
}

void ReliableLink::send_ack() {
  const size_t n = encode_frame(frame_, nak_pending_ ? kFlagNak : 0, 0, expected_, nullptr, 0);
  ack_pending_ = false;
  nak_pending_ = false;
  ++stats_.acks_sent;
  if (out_ != nullptr) out_->write_frame(frame_, n);
}

void ReliableLink::on_bytes(const uint8_t* data, size_t n, int64_t now_ns) {
  while (n > 0) {
    const size_t took = decoder_.feed(data, n);
    data += took;
    n -= took;
    FrameView f;
    while (decoder_.next(f)) on_frame(f, now_ns);
  }
  if (ack_pending_) send_ack();
}

void ReliableLink::on_frame(const FrameView& f, int64_t now_ns) {
  // Cumulative ack: everything before f.ack has arrived at the peer.
  const uint16_t acked = static_cast<uint16_t>(f.ack - static_cast<uint16_t>(next_seq_ - count_));
  if (acked > 0 && acked <= count_) {
    // Round-trip sample from the newest acknowledged frame if it was sent only once (Karn);
    // RTO = srtt + 4 rttvar (RFC 6298), within [rto_ns, rto_max_ns].
    const Slot& newest = slots_[(head_ + static_cast<int>(acked) - 1) % kMaxWindow];
    if (!newest.retransmitted) {
      const double rtt = static_cast<double>(now_ns - newest.sent_ns);
      if (srtt_ns_ <= 0.0) {
        srtt_ns_ = rtt;
        rttvar_ns_ = 0.5 * rtt;
      } else {
        rttvar_ns_ = 0.75 * rttvar_ns_ + 0.25 * std::fabs(srtt_ns_ - rtt);
        srtt_ns_ = 0.875 * srtt_ns_ + 0.125 * rtt;
      }
    }
    head_ = (head_ + static_cast<int>(acked)) % kMaxWindow;
    count_ -= static_cast<int>(acked);
    timer_start_ns_ = progress_ns_ = now_ns;
    rto_ns_ = base_rto_ns();
  }
  if ((f.flags & kFlagNak) && count_ > 0 && now_ns - last_fast_ns_ >= params_.fast_retransmit_gap_ns) {
    // The peer saw a gap (a frame after a lost or reordered one): go back N at once instead of
    // waiting for the timeout (fast retransmit), at most once per fast_retransmit_gap.
    last_fast_ns_ = now_ns;
    for (int i = 0; i < count_; ++i) transmit((head_ + i) % kMaxWindow, true, now_ns);
    timer_start_ns_ = now_ns;
  }
  if (!(f.flags & kFlagData)) return;
  if (f.flags & kFlagReset) {
    // Honour a reset once per epoch (retransmissions of the same reset are duplicates).
    const int epoch = f.flags >> 4;
    if (epoch != peer_epoch_) {
      // The peer restarted: what we still had in flight was for its previous incarnation.
      // Restart our own numbering too (our next frame carries kFlagReset). First: reset() also
      // clears the receive side, which this frame now sets.
      if (!reset_pending_ && (next_seq_ != 0 || count_ != 0)) reset();
      peer_epoch_ = epoch;
      expected_ = f.seq;
    }
  }
  ack_pending_ = true;
  if (f.seq == expected_) {
    ++expected_;
    ++stats_.delivered;
    if (in_ != nullptr) in_->on_payload(f.payload, f.len);
  } else if (static_cast<uint16_t>(expected_ - f.seq) <= 32768) {
    ++stats_.duplicates_dropped;
  } else {
    ++stats_.out_of_order_dropped;
    nak_pending_ = true;  // a frame ahead of the expected one: something was lost
  }
}

void ReliableLink::poll(int64_t now_ns) {
  if (count_ == 0 || now_ns - timer_start_ns_ < rto_ns_) return;
  for (int i = 0; i < count_; ++i) transmit((head_ + i) % kMaxWindow, true, now_ns);
  timer_start_ns_ = now_ns;
  rto_ns_ = rto_ns_ * 2 > params_.rto_max_ns ? params_.rto_max_ns : rto_ns_ * 2;
}

}  // namespace feedloop::protocol

namespace feedloop::protocol {

void ReliableLink::retransmit_now(int64_t now_ns) {
  rto_ns_ = base_rto_ns();
  for (int i = 0; i < count_; ++i) transmit((head_ + i) % kMaxWindow, true, now_ns);
  timer_start_ns_ = progress_ns_ = now_ns;
}

}  // namespace feedloop::protocol
