// Frames on the byte stream (docs/protocol.md, "Frames"):
//
//   0x7E | len | flags | seq lo | seq hi | ack lo | ack hi | payload[len] | crc16 hi | crc16 lo
//
// len <= kMaxPayload; seq and ack are 16-bit little endian (a frame would have to be delayed by
// 65536 frames to be mistaken for a new one); the CRC16-CCITT covers len..payload. flags: kFlagData (the frame carries a
// sequenced payload numbered seq), kFlagReset (the sender restarted its link: the receiver
// resets its expected sequence to seq, once per link epoch: flags bits 4-7), kFlagNak (on a
// pure ack: the receiver saw a gap, retransmit now). ack is the next sequence number the sender expects
// (cumulative acknowledgement). A receiver resynchronises by length + CRC: on a bad length or
// CRC it drops one byte and looks for the next sync byte. No byte stuffing.
// Header-only, fixed buffers: used by the host and the device.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "drivers/protocol/crc16.hpp"

namespace feedloop::protocol {

inline constexpr uint8_t kSync = 0x7E;
inline constexpr size_t kMaxPayload = 240;
inline constexpr size_t kHeaderBytes = 7;
inline constexpr size_t kFrameOverhead = kHeaderBytes + 2;
inline constexpr size_t kMaxFrame = kMaxPayload + kFrameOverhead;
inline constexpr uint8_t kFlagData = 0x01;
inline constexpr uint8_t kFlagReset = 0x02;
inline constexpr uint8_t kFlagNak = 0x04;  // pure ack: a frame after a gap arrived

struct FrameView {
  uint8_t flags = 0;
  uint16_t seq = 0;
  uint16_t ack = 0;
  const uint8_t* payload = nullptr;
  size_t len = 0;
};

// Writes a frame into out (at least kMaxFrame bytes); returns its size, 0 if len is too big.
inline size_t encode_frame(uint8_t* out, uint8_t flags, uint16_t seq, uint16_t ack, const uint8_t* payload,
                           size_t len) {
  if (len > kMaxPayload) return 0;
  out[0] = kSync;
  out[1] = static_cast<uint8_t>(len);
  out[2] = flags;
  out[3] = static_cast<uint8_t>(seq & 0xFF);
  out[4] = static_cast<uint8_t>(seq >> 8);
  out[5] = static_cast<uint8_t>(ack & 0xFF);
  out[6] = static_cast<uint8_t>(ack >> 8);
  if (len > 0) std::memcpy(out + kHeaderBytes, payload, len);
  const uint16_t crc = crc16_ccitt(out + 1, kHeaderBytes - 1 + len);
  out[kHeaderBytes + len] = static_cast<uint8_t>(crc >> 8);
  out[kHeaderBytes + len + 1] = static_cast<uint8_t>(crc & 0xFF);
  return len + kFrameOverhead;
}

struct FrameDecoderStats {
  uint64_t frames = 0;
  uint64_t crc_errors = 0;
  uint64_t bad_lengths = 0;
  uint64_t bytes_skipped = 0;
};

// Streaming decoder: feed() any chunking of the byte stream; next() yields whole frames.
class FrameDecoder {
 public:
  // Appends bytes; returns how many were taken (fewer if the internal buffer is full: call
  // next() until it returns false, then feed the rest).
  size_t feed(const uint8_t* data, size_t n) {
    const size_t room = sizeof buf_ - len_;
    const size_t take = n < room ? n : room;
    std::memcpy(buf_ + len_, data, take);
    len_ += take;
    return take;
  }
  // Extracts the next valid frame (its payload stays valid until the next call to feed/next).
  bool next(FrameView& f) {
    consume_pending();
    for (;;) {
      size_t start = 0;
      while (start < len_ && buf_[start] != kSync) ++start;
      if (start > 0) {
        stats_.bytes_skipped += start;
        drop(start);
      }
      if (len_ < kHeaderBytes) return false;
      const size_t plen = buf_[1];
      if (plen > kMaxPayload) {
        ++stats_.bad_lengths;
        ++stats_.bytes_skipped;
        drop(1);
        continue;
      }
      const size_t total = plen + kFrameOverhead;
      if (len_ < total) return false;
      const uint16_t crc = crc16_ccitt(buf_ + 1, kHeaderBytes - 1 + plen);
      const uint16_t got = static_cast<uint16_t>((buf_[kHeaderBytes + plen] << 8) | buf_[kHeaderBytes + plen + 1]);
      if (crc != got) {
        ++stats_.crc_errors;
        ++stats_.bytes_skipped;
        drop(1);
        continue;
      }
      f.flags = buf_[2];
      f.seq = static_cast<uint16_t>(buf_[3] | (buf_[4] << 8));
      f.ack = static_cast<uint16_t>(buf_[5] | (buf_[6] << 8));
      f.payload = buf_ + kHeaderBytes;
      f.len = plen;
      pending_ = total;
      ++stats_.frames;
      return true;
    }
  }
  void clear() { len_ = pending_ = 0; }
  const FrameDecoderStats& stats() const { return stats_; }

 private:
  void consume_pending() {
    if (pending_ > 0) {
      drop(pending_);
      pending_ = 0;
    }
  }
  void drop(size_t n) {
    std::memmove(buf_, buf_ + n, len_ - n);
    len_ -= n;
  }
  uint8_t buf_[2 * kMaxFrame] = {};
  size_t len_ = 0;
  size_t pending_ = 0;
  FrameDecoderStats stats_;
};

}  // namespace feedloop::protocol
