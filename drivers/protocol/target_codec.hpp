// Host side of QUEUE_TARGET: compresses samples of the desired carriage trajectory r(t) into the
// knots of a piecewise-linear r with a bounded error (the swinging-door algorithm, O(1) per
// sample, no allocation). Every sample pushed lies within max_error_nm of the line through the
// knots (positions rounded to whole nm are accounted for). A knot is also forced once a piece
// spans max_span_ticks, so the device's horizon keeps up with the stream.
//
// Usage (per axis, on the host's motion stage): push(clock, r_nm) for each sample in increasing
// clock; each returned knot goes into the next QUEUE_TARGET (encode_queue_target). At the end of
// a motion (or before a pause in the stream), flush() emits the last sample as a knot.
// Between samples the device interpolates linearly; the host's sampling period bounds the error
// there (a dt^2 / 8 for acceleration a), so sample at least as fast as that requires.
#pragma once

#include <cstdint>

#include "drivers/device/target_queue.hpp"

namespace feedloop::protocol {

class TargetCompressor {
 public:
  // max_error_nm >= 2; max_span_ticks > 0.
  void configure(double max_error_nm, int64_t max_span_ticks) {
    eps_ = max_error_nm - 1.0;  // room for rounding the knot to whole nm
    max_span_ = max_span_ticks;
    reset();
  }
  void reset() { have_anchor_ = have_prev_ = false; }

  // Returns true with a knot to send (emitted for an earlier sample) when there is one.
  bool push(int64_t clock, double pos_nm, device::TargetKnot& knot) {
    if (!have_anchor_) {
      anchor_ = {clock, static_cast<int64_t>(pos_nm >= 0 ? pos_nm + 0.5 : pos_nm - 0.5)};
      have_anchor_ = true;
      have_prev_ = false;
      knot = anchor_;
      return true;  // the first sample is a knot
    }
    const double dt = static_cast<double>(clock - anchor_.clock);
    const double d = pos_nm - static_cast<double>(anchor_.pos_nm);
    const double lo = (d - eps_) / dt, hi = (d + eps_) / dt;
    if (!have_prev_) {
      lo_ = lo;
      hi_ = hi;
      prev_clock_ = clock;
      prev_pos_ = pos_nm;
      have_prev_ = true;
      return false;
    }
    const double nlo = lo > lo_ ? lo : lo_, nhi = hi < hi_ ? hi : hi_;
    if (nlo <= nhi && clock - anchor_.clock <= max_span_) {
      lo_ = nlo;
      hi_ = nhi;
      prev_clock_ = clock;
      prev_pos_ = pos_nm;
      return false;
    }
    // The previous sample ends a piece: emit it on the best line from the anchor, then the
    // current sample starts the next piece's bounds.
    knot = emit_prev();
    const double dt2 = static_cast<double>(clock - anchor_.clock);
    const double d2 = pos_nm - static_cast<double>(anchor_.pos_nm);
    lo_ = (d2 - eps_) / dt2;
    hi_ = (d2 + eps_) / dt2;
    prev_clock_ = clock;
    prev_pos_ = pos_nm;
    have_prev_ = true;
    return true;
  }

  // Emits the last sample as a knot (false when there is nothing pending).
  bool flush(device::TargetKnot& knot) {
    if (!have_prev_) return false;
    knot = emit_prev();
    have_prev_ = false;
    return true;
  }

 private:
  device::TargetKnot emit_prev() {
    const double dt = static_cast<double>(prev_clock_ - anchor_.clock);
    double slope = (prev_pos_ - static_cast<double>(anchor_.pos_nm)) / dt;  // through the sample
    if (slope < lo_) slope = lo_;
    if (slope > hi_) slope = hi_;
    const double p = static_cast<double>(anchor_.pos_nm) + slope * dt;
    anchor_ = {prev_clock_, static_cast<int64_t>(p >= 0 ? p + 0.5 : p - 0.5)};
    return anchor_;
  }

  double eps_ = 999.0;
  int64_t max_span_ = INT64_MAX;
  bool have_anchor_ = false, have_prev_ = false;
  device::TargetKnot anchor_;
  int64_t prev_clock_ = 0;
  double prev_pos_ = 0.0;
  double lo_ = 0.0, hi_ = 0.0;
};

}  // namespace feedloop::protocol
