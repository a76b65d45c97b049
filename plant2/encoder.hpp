// The linear encoder of the second simulator: the carriage position through a transport delay,
// a scale error about the power-on position, the interpolation error at the scale's signal period,
// then quantisation. The delay line holds the carriage's position at every integration step
// (fixed capacity, allocated once) and is read with linear interpolation.
#pragma once

#include <cstddef>
#include <vector>

#include "plant2/params.hpp"

namespace feedloop::plant2 {

class Encoder {
 public:
  // `step_s`: the smallest integration step the delay line must cover at max_delay_s.
  Encoder(const EncoderParams& p, double origin_m, double step_s);

  // Records the true carriage position at time t_s (times increasing). Samples closer than
  // `step_s` / 2 to the newest held one replace it, so the line reaches max_delay_s whatever the
  // caller's step.
  void push(double t_s, double x_m);

  // The true position delay_s before t_s (the oldest or newest held value beyond the line).
  double delayed_m(double t_s) const;

  // The reading before quantisation: origin + scale (x - origin) + interpolation error, at the
  // position delay_s before t_s.
  double raw_m(double t_s) const { return reading_of(delayed_m(t_s)); }
  // The quantised reading (resolution_m steps, rounded).
  double quantised_m(double t_s) const;

  // The reading the encoder gives for a carriage at x (no delay, no quantisation).
  double reading_of(double x_m) const;

  const EncoderParams& params() const { return p_; }

 private:
  EncoderParams p_;
  double origin_m_;
  double min_spacing_s_;
  std::vector<double> t_;
  std::vector<double> x_;
  size_t head_ = 0;  // next slot to write
  size_t count_ = 0;
};

}  // namespace feedloop::plant2
