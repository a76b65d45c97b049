// Wire encoding of compressed step runs (the body of a QUEUE_STEPS message, docs/protocol.md):
//
//   varint first_clock                       MCU clock of the step before the first run (P)
//   per run: varint (count << 1 | dir_neg)   count >= 1, dir_neg = 1 for direction -1
//            zigzag varint (interval - prev) prev = last interval of the previous run in this
//                                            batch (interval + (count-1)*add), 0 for the first
//            zigzag varint add
//
// Because consecutive runs continue each other's interval, the delta is usually one byte, so a
// run usually costs three bytes. Header-only and allocation-free: the device decodes with it.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/protocol/varint.hpp"
#include "drivers/stepgen/step_run.hpp"

namespace feedloop::stepgen {

class RunEncoder {
 public:
  // Writes into out[0..cap). first_clock is the reference of the first run.
  bool begin(uint8_t* out, size_t cap, uint64_t first_clock) {
    out_ = out;
    cap_ = cap;
    prev_interval_ = 0;
    runs_ = steps_ = 0;
    pos_ = protocol::put_varint(out_, 0, cap_, first_clock);
    return pos_ != 0;
  }
  // False (and nothing written) when the run does not fit.
  bool append(const StepRun& r) {
    uint8_t tmp[32];
    size_t p = protocol::put_varint(tmp, 0, sizeof tmp,
                                    (static_cast<uint64_t>(r.count) << 1) | (r.direction < 0 ? 1u : 0u));
    p = protocol::put_varint(tmp, p, sizeof tmp, protocol::zigzag(r.interval_ticks - prev_interval_));
    p = protocol::put_varint(tmp, p, sizeof tmp, protocol::zigzag(r.add_ticks));
    if (pos_ + p > cap_) return false;
    for (size_t i = 0; i < p; ++i) out_[pos_ + i] = tmp[i];
    pos_ += p;
    prev_interval_ = r.interval_ticks + static_cast<int64_t>(r.count - 1) * r.add_ticks;
    ++runs_;
    steps_ += r.count;
    return true;
  }
  size_t size() const { return pos_; }
  uint32_t runs() const { return runs_; }
  uint64_t steps() const { return steps_; }

 private:
  uint8_t* out_ = nullptr;
  size_t cap_ = 0, pos_ = 0;
  int64_t prev_interval_ = 0;
  uint32_t runs_ = 0;
  uint64_t steps_ = 0;
};

class RunDecoder {
 public:
  bool begin(const uint8_t* in, size_t len) {
    in_ = in;
    len_ = len;
    pos_ = 0;
    prev_interval_ = 0;
    uint64_t fc = 0;
    if (!protocol::get_varint(in_, len_, pos_, fc)) return false;
    first_clock_ = static_cast<int64_t>(fc);
    return true;
  }
  int64_t first_clock() const { return first_clock_; }
  bool done() const { return pos_ >= len_; }
  // False on malformed input.
  bool next(StepRun& r) {
    uint64_t c = 0, di = 0, a = 0;
    if (!protocol::get_varint(in_, len_, pos_, c) || !protocol::get_varint(in_, len_, pos_, di) ||
        !protocol::get_varint(in_, len_, pos_, a))
      return false;
    if ((c >> 1) == 0 || (c >> 1) > 0xFFFFFFFFu) return false;
    r.count = static_cast<uint32_t>(c >> 1);
    r.direction = (c & 1) ? -1 : 1;
    const int64_t add = protocol::unzigzag(a);
    if (add < INT32_MIN || add > INT32_MAX) return false;
    r.add_ticks = static_cast<int32_t>(add);
    // Intervals that do not fit 64 bits are malformed (checked: the input is untrusted).
    int64_t growth = 0;
    if (__builtin_add_overflow(prev_interval_, protocol::unzigzag(di), &r.interval_ticks) ||
        __builtin_mul_overflow(static_cast<int64_t>(r.count - 1), add, &growth) ||
        __builtin_add_overflow(r.interval_ticks, growth, &prev_interval_))
      return false;
    return true;
  }

 private:
  const uint8_t* in_ = nullptr;
  size_t len_ = 0, pos_ = 0;
  int64_t prev_interval_ = 0;
  int64_t first_clock_ = 0;
};

}  // namespace feedloop::stepgen
