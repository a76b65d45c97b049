// feedloop's closed-loop telemetry for the web page: the tracking error over time and over X/Y,
// per layer. Sampled by the web server's tick (not the servo thread) from the status snapshot.
// The engine publishes e_t as a running mean and max since start (MachineStatus); the value
// "now" is the mean over the samples taken since the previous tick: (sum_now - sum_prev) /
// (n_now - n_prev). A layer is a Z height at which the nozzle moved while the error was sampled.
#pragma once

#include <nlohmann/json.hpp>

#include <deque>
#include <vector>

#include "engine/machine.hpp"

namespace feedloop::web {

class TrackingTelemetry {
 public:
  struct Point {
    double t_s;  // since the telemetry started
    double x_mm, y_mm, z_mm;
    double error_mm;  // mean |e_t| since the previous point
    double max_mm;    // the running max at this point
  };
  struct Layer {
    double z_mm = 0.0;
    double sum_mm = 0.0;  // sum of point errors
    double max_mm = 0.0;
    uint64_t points = 0;
  };

  // Returns true when a point was added (new error samples since the last call).
  bool sample(double t_s, const engine::MachineStatus& s);
  // The object feedloop_tracking: now, mean, max, lost steps, per layer {z_mm, mean_mm, max_mm,
  // points}.
  nlohmann::json summary(const engine::MachineStatus& s) const;
  // Points since index `from` (for the page's incremental fetch), at most `limit`.
  nlohmann::json points(size_t from, size_t limit) const;
  size_t total_points() const { return dropped_ + points_.size(); }
  double now_mm() const { return now_mm_; }
  const std::vector<Layer>& layers() const { return layers_; }

  static constexpr size_t kMaxPoints = 200000;  // about 5.5 h at 10 Hz; older points are dropped

 private:
  std::deque<Point> points_;
  size_t dropped_ = 0;
  std::vector<Layer> layers_;
  size_t current_ = 0;  // the layer being printed
  uint64_t last_samples_ = 0;
  double last_sum_ = 0.0;
  double now_mm_ = 0.0;
};

}  // namespace feedloop::web
