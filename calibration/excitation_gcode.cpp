// The calibration program as G-code (excitation_gcode.hpp).
#include "calibration/excitation_gcode.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

namespace feedloop::calibration {
namespace {

class Writer {
 public:
  explicit Writer(char axis) : axis_(axis) {}
  void move(double pos_mm, double speed_mm_s) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "G1 %c%.5f F%.1f\n", axis_, pos_mm, speed_mm_s * 60.0);
    text_ += buf;
    pos_mm_ = pos_mm;
  }
  void dwell(double s) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "G4 P%.0f\n", s * 1e3);
    text_ += buf;
  }
  void line(const char* s) { (text_ += s) += '\n'; }
  double pos_mm() const { return pos_mm_; }
  std::string& text() { return text_; }

 private:
  char axis_;
  double pos_mm_ = 0.0;
  std::string text_;
};

}  // namespace

std::string excitation_gcode(const ExcitationGcodeOptions& o) {
  Writer w(o.axis);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const auto between = [&](double lo, double hi) { return lo + (hi - lo) * uni(rng); };
  w.line("; feedloop calibrate: the calibration program (calibration/excitation_gcode.hpp)");
  w.line("G90");
  w.move(o.start_mm, o.max_speed_mm_s);
  w.dwell(0.3);
  const int sections = 4;
  for (int c = 0; c < o.cycles; ++c) {
    for (int s = 0; s < sections; ++s) {
      // The section's base: spread over the travel, forward on even cycles and back on odd ones.
      const double f = (s + 0.5) / sections;
      const double base = o.start_mm + o.travel_mm * (c % 2 == 0 ? f : 1.0 - f);
      w.move(base, o.max_speed_mm_s);
      if (s == 0) {  // 1. random small moves around the base, each followed by a dwell
        double t = 0.0, x = base;
        while (t < o.random_s) {
          const double step = between(o.step_min_mm, o.step_max_mm);
          // Random sign, pulled back towards the base so the walk stays near it.
          const double toward = x > base ? -1.0 : 1.0;
          x += (uni(rng) < 0.6 ? toward : -toward) * step;
          w.move(x, o.max_speed_mm_s);
          const double d = between(o.dwell_min_s, o.dwell_max_s);
          w.dwell(d);
          t += d + 2.0 * std::sqrt(step / o.accel_mm_s2);
        }
      } else if (s == 1) {  // 2. the sweep: back-and-forth half periods, f rising exponentially
        double t = 0.0;
        const double k = std::log(o.sweep_f_end_hz / o.sweep_f_start_hz) / o.sweep_s;
        int sign = 1;
        while (t < o.sweep_s) {
          const double f_hz = o.sweep_f_start_hz * std::exp(k * t);
          const double d = std::min(2.0 * o.sweep_amplitude_mm, o.accel_mm_s2 / (16.0 * f_hz * f_hz));
          // Peak speed of the triangle profile (a tau / 2 = 2 d f), capped by max_speed.
          w.move(base + (sign > 0 ? d : 0.0), std::min(2.0 * d * f_hz * 1.05, o.max_speed_mm_s));
          sign = -sign;
          t += 0.5 / f_hz;
        }
        w.move(base, o.max_speed_mm_s);
      } else if (s == 2) {  // 3. reversals at several speeds
        for (double v : o.reversal_speeds_mm_s)
          for (int r = 0; r < o.reversals_per_speed; ++r) {
            w.move(base + o.reversal_span_mm, v);
            w.move(base, v);
          }
      } else if (o.run_mm > 0.0) {  // 4. constant-speed runs forward and back
        w.move(base + o.run_mm / 2.0, o.run_speed_mm_s);
        w.move(base - o.run_mm / 2.0, o.run_speed_mm_s);
        w.move(base, o.run_speed_mm_s);
      }
    }
  }
  w.move(o.start_mm, o.max_speed_mm_s);
  w.line("M400");
  return std::move(w.text());
}

}  // namespace feedloop::calibration
