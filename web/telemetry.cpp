#include "web/telemetry.hpp"

#include <cmath>

namespace feedloop::web {

using nlohmann::json;

bool TrackingTelemetry::sample(double t_s, const engine::MachineStatus& s) {
  const double sum = s.tracking_error_mean_mm * static_cast<double>(s.tracking_error_samples);
  if (s.tracking_error_samples < last_samples_) {  // the machine was rebuilt (restart, reload)
    last_samples_ = 0;
    last_sum_ = 0.0;
  }
  if (s.tracking_error_samples == last_samples_) return false;
  const double n = static_cast<double>(s.tracking_error_samples - last_samples_);
  now_mm_ = std::max(0.0, (sum - last_sum_) / n);
  last_samples_ = s.tracking_error_samples;
  last_sum_ = sum;
  const Point p{t_s, s.pos_mm[0], s.pos_mm[1], s.pos_mm[2], now_mm_, s.tracking_error_max_mm};
  points_.push_back(p);
  if (points_.size() > kMaxPoints) {
    points_.pop_front();
    ++dropped_;
  }
  // A Z seen before (a travel hop returning) continues its layer.
  if (layers_.empty() || std::fabs(layers_[current_].z_mm - p.z_mm) > 1e-6) {
    current_ = layers_.size();
    for (size_t i = 0; i < layers_.size(); ++i)
      if (std::fabs(layers_[i].z_mm - p.z_mm) <= 1e-6) current_ = i;
    if (current_ == layers_.size()) layers_.push_back(Layer{p.z_mm, 0.0, 0.0, 0});
  }
  Layer& l = layers_[current_];
  l.sum_mm += p.error_mm;
  l.max_mm = std::max(l.max_mm, p.error_mm);
  ++l.points;
  return true;
}

json TrackingTelemetry::summary(const engine::MachineStatus& s) const {
  json layers = json::array();
  for (const Layer& l : layers_)
    layers.push_back({{"z_mm", l.z_mm},
                      {"mean_mm", l.points ? l.sum_mm / static_cast<double>(l.points) : 0.0},
                      {"max_mm", l.max_mm},
                      {"points", l.points}});
  return {{"error_now_mm", now_mm_},
          {"error_mean_mm", s.tracking_error_mean_mm},
          {"error_max_mm", s.tracking_error_max_mm},
          {"samples", s.tracking_error_samples},
          {"lost_step_events", s.lost_step_events},
          {"points", total_points()},
          {"layers", layers}};
}

json TrackingTelemetry::points(size_t from, size_t limit) const {
  json t = json::array(), x = json::array(), y = json::array(), z = json::array(),
       e = json::array();
  size_t i = from < dropped_ ? 0 : from - dropped_;
  for (size_t n = 0; i < points_.size() && n < limit; ++i, ++n) {
    const Point& p = points_[i];
    t.push_back(p.t_s);
    x.push_back(p.x_mm);
    y.push_back(p.y_mm);
    z.push_back(p.z_mm);
    e.push_back(p.error_mm);
  }
  return {{"from", std::max(from, dropped_)},
          {"next", dropped_ + i},
          {"t_s", t},
          {"x_mm", x},
          {"y_mm", y},
          {"z_mm", z},
          {"error_mm", e}};
}

}  // namespace feedloop::web
