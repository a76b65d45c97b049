// Tracking metrics exactly as closed-loop-gantry-thesis Sect. 5.2 defines them, on samples every
// servo period (1 ms) from the start of the test path to its planned end:
//   mean trajectory error  e_t = 1/N sum_i sqrt((x(i) - x_t(i))^2 + (y(i) - y_t(i))^2)
//     (x_t: the commanded trajectory at sample i; with its standard deviation, and the maximum)
//   radial error (circle)  e_r = sqrt(1/N sum_i (sqrt((x(i) - x_c)^2 + (y(i) - y_c)^2) - r_c)^2)
//     (x_c, y_c, r_c: centre and radius of the commanded circle; the 50-chord polygon's own
//      deviation from it, r_c (1 - cos(pi/50)) = 0.04 mm at mid-chord, is part of e_r, as in the
//      thesis, whose G-code was the same polygon)
// x(i) is the simulated machine's true nozzle (carriage) position, x_t(i) the planned nozzle
// position at the print time being executed at sample i.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace feedloop::bench {

struct TrackSample {
  double t_s = 0.0;             // print time being executed
  double ref_mm[3] = {0, 0, 0};  // planned nozzle
  double act_mm[3] = {0, 0, 0};  // actual nozzle
};

struct Circle {
  double cx_mm, cy_mm, r_mm;
};

// The test path inside a run that first travels to its start and dwells there: from the last
// sample of the last rest of at least `min_rest_samples` before the final motion, to the first
// sample at the final rest. Indices into `s` (inclusive); false when the plan never moves.
bool find_pattern_window(const std::vector<TrackSample>& s, int min_rest_samples, size_t& i0, size_t& i1);

struct TrackMetrics {
  size_t samples = 0;
  double e_t_mm = 0.0;      // mean trajectory error
  double e_t_std_mm = 0.0;  // its standard deviation (population)
  double e_max_mm = 0.0;    // largest sample error
  double e_r_mm = -1.0;     // radial RMS error (circle only; < 0: not a circle)
  double time_s = 0.0;      // planned time of the path (first to last sample of the window)
};

TrackMetrics track_metrics(const std::vector<TrackSample>& s, size_t i0, size_t i1,
                           const std::optional<Circle>& circle);

// Checks the metric code on synthetic samples with known answers (no simulator needed). Returns
// an empty string when every check passes, else what failed.
std::string metrics_self_test();

}  // namespace feedloop::bench
