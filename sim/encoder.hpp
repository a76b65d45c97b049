// Linear encoder model (AS5311-like, thesis Sect. 2.2): quantised carriage position with seeded
// Gaussian noise and a sampling delay, plus the short position history the delay reads from.
//
// Counts are zero at the carriage's power-on position (an incremental reading, like the MCU's
// step counter, which also starts at zero), so cmd_mm and meas_mm start together.
#pragma once

#include <cstddef>  // size_t
#include <cstdint>  // int64_t
#include <vector>

#include "core/result.hpp"
#include "core/rng.hpp"

namespace feedloop::sim {

struct EncoderParams {
  double resolution_um = 0.49;    // AS5311: 2 mm pole pair / 4096 interpolation steps (thesis: 0.49 um)
  double noise_um = 0.3;          // standard deviation of the Gaussian reading noise (0 = none)
  double sampling_delay_s = 0.0;  // the reading at t shows the position at t - delay
  // Index marks (the AS5311's index: once per 2 mm pole pair): the index line is high while the
  // true position lies within one count above a mark, with no reading noise (a decoder latches the
  // mark's edge). The plants put the marks at odd multiples of half a period in machine
  // coordinates: a switch at a whole millimetre sits mid-way between two. 0: no index.
  double index_period_mm = 0.0;
};

Status validate(const EncoderParams& p);

// Converts a true position (mm, relative to the zero) into counts. Owner: the plant that holds it.
class LinearEncoder {
 public:
  LinearEncoder(const EncoderParams& p, uint64_t seed) : p_(p), rng_(seed) {}
  // RT-safe: no allocation.
  int64_t counts(double pos_mm);
  double mm_per_count() const { return p_.resolution_um * 1e-3; }
  const EncoderParams& params() const { return p_; }

 private:
  EncoderParams p_;
  Rng rng_;
};

// Fixed-capacity ring of (time, value) samples, pushed in increasing time; value_at(t) interpolates
// linearly and clamps to the oldest/newest sample. Capacity is fixed at construction.
// A sample closer than min_spacing_s to the one before the newest replaces the newest: any two
// samples two apart are min_spacing_s apart or more, so the ring spans at least
// (capacity - 1) / 2 x min_spacing_s however often samples come. (A plant pushes one at every
// input event too, beside its substeps: with the ring sized for the substeps alone, the first
// simulator's Y axis, 8.3 ms of time_delay, read its carriage 3-4 ms late while it stepped fast:
// the delay shrank with the step rate.)
class History {
 public:
  explicit History(size_t capacity, double min_spacing_s = 0.0);
  void clear(double t_s, double value);
  // RT-safe.
  void push(double t_s, double value);
  double value_at(double t_s) const;

 private:
  std::vector<double> t_, v_;
  size_t head_ = 0;  // index of the newest sample
  size_t size_ = 0;
  double min_spacing_s_ = 0.0;
};

}  // namespace feedloop::sim
