// Host-side estimate of one MCU clock (the only place that converts between host time and MCU
// ticks, STYLE.md convention 2). Each clock query gives a sample (host send time s, host receive
// time r, MCU clock c read in between). The MCU read happened at an unknown time in [s, r]; the
// midpoint m = (s + r)/2 is off by at most rtt/2. The model is  c = c_ref + f (m - m_ref)
// (offset and frequency f, i.e. drift): least squares over the fast round trips among the last
// `window` samples (rtt <= min + max(rtt_floor, 2 (q25 - min)); slow round trips, e.g.
// retransmitted queries, carry little information; Klipper's clocksync similarly prefers the
// minimum-RTT sample). Averaging many samples cancels the
// zero-mean part of the up/down asymmetry; a systematic asymmetry cannot be observed by any
// round-trip method. Until the kept samples span min_span_s, the nominal frequency is used and
// only the offset is fitted. The offset then comes from intersecting the recent samples
// feasible intervals (see fit()), which converges to the fastest round trips.
// The fit costs tens of microseconds per sample (256 samples, a ternary search of 80 steps): with a
// transport that has an I/O thread it runs there (ClockSyncChannel, clock_sync_channel.hpp) and
// the timing thread reads the ClockEstimate it publishes. Owner: one thread.
#pragma once

#include <cstdint>
#include <vector>

#include "drivers/stepgen/step_generator.hpp"

namespace feedloop::drivers {

struct ClockSyncParams {
  double nominal_hz = 20e6;
  int window = 256;  // 25 s at 10 queries/s: the frequency needs a long baseline
  double rtt_floor_s = 50e-6;
  double min_span_s = 0.5;
  int offset_window = 64;  // samples intersected for the offset
};

// The result of a fit: the line c = c_ref + f (t - m_ref) and the round trips behind it. Trivially
// copyable (published through a seqlock); every method RT-safe.
class ClockEstimate {
 public:
  bool ready() const { return samples_ > 0; }
  // Estimated MCU clock (ticks, real-valued) at host time host_s, and the inverse.
  double clock_at(double host_s) const { return c_ref_ + freq_hz_ * (host_s - m_ref_); }
  double host_time_at(double clock) const { return m_ref_ + (clock - c_ref_) / freq_hz_; }
  double freq_hz() const { return freq_hz_; }
  double min_rtt_s() const { return min_rtt_s_; }
  double last_rtt_s() const { return last_rtt_s_; }
  double mean_rtt_s() const { return mean_rtt_s_; }  // over the window
  int samples() const { return samples_; }
  // Print time (= host time here) -> ticks, for the step generator.
  stepgen::TickMap tick_map() const { return {c_ref_ - freq_hz_ * m_ref_, freq_hz_}; }

 private:
  friend class ClockSync;
  double freq_hz_ = 20e6, c_ref_ = 0.0, m_ref_ = 0.0, min_rtt_s_ = 0.0, last_rtt_s_ = 0.0, mean_rtt_s_ = 0.0;
  int samples_ = 0;
};

class ClockSync {
 public:
  // Allocates the window (once per identify).
  void configure(const ClockSyncParams& p);
  // Adds a sample and fits (no allocation).
  void add_sample(double send_s, double recv_s, int64_t mcu_clock);
  const ClockEstimate& estimate() const { return est_; }
  // The estimate before any sample (the nominal rate, not ready()).
  static ClockEstimate nominal(const ClockSyncParams& p) {
    ClockEstimate e;
    e.freq_hz_ = p.nominal_hz;
    return e;
  }
  bool ready() const { return est_.ready(); }
  double clock_at(double host_s) const { return est_.clock_at(host_s); }
  double host_time_at(double clock) const { return est_.host_time_at(clock); }
  double freq_hz() const { return est_.freq_hz(); }
  double min_rtt_s() const { return est_.min_rtt_s(); }
  double last_rtt_s() const { return est_.last_rtt_s(); }
  double mean_rtt_s() const { return est_.mean_rtt_s(); }
  int samples() const { return est_.samples(); }
  stepgen::TickMap tick_map() const { return est_.tick_map(); }

 private:
  void fit();
  double window_mean_rtt_s() const;
  struct Sample {
    double mid_s, rtt_s;
    int64_t clock;
  };
  ClockSyncParams p_;
  std::vector<Sample> ring_;
  std::vector<double> scratch_;
  int head_ = 0, count_ = 0;
  ClockEstimate est_;
};

}  // namespace feedloop::drivers
