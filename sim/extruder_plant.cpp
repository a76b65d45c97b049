// The compliant extruder (see extruder_plant.hpp).
#include "sim/extruder_plant.hpp"

#include <algorithm>  // std::clamp, std::max
#include <cmath>      // std::pow, std::exp

namespace feedloop::sim {

ExtruderPlant::ExtruderPlant(const ExtruderPlantParams& p) : p_(p) {
  const double r = 0.5 * p_.filament_diameter_mm;
  area_mm2_ = 3.14159265358979323846 * r * r;
  const double p_ref = p_.force_ref_n / area_mm2_;  // N/mm^2 = MPa
  c_ = p_.flow_ref_mm3_s / std::pow(p_ref, p_.flow_exponent);
  reset(0.0);
}

void ExtruderPlant::reset(double motor_mm) {
  play_out_mm_ = motor_mm;
  filament_mm_ = motor_mm;
  force_n_ = 0.0;
  q_noz_mm3_s_ = 0.0;
  volume_mm3_ = 0.0;
}

double ExtruderPlant::flow_for_force(double force_n) const {
  if (force_n <= 0.0) return 0.0;
  return c_ * std::pow(force_n / area_mm2_, p_.flow_exponent);
}

void ExtruderPlant::step(double motor_mm, double dt_s) {
  // Play: the far end follows the motor only once the motor has crossed the dead band.
  play_out_mm_ = std::clamp(play_out_mm_, motor_mm - 0.5 * p_.play_mm, motor_mm + 0.5 * p_.play_mm);
  // Filament consumed by the nozzle over dt: midpoint rule on dx_f/dt = q(F) / A_f with
  // F = k_f (y - x_f) (the spring's time constant is > 10 ms at every flow, dt is 0.1-0.2 ms).
  auto rate = [&](double x) {
    return flow_for_force(p_.stiffness_n_per_mm * (play_out_mm_ - x)) / area_mm2_;
  };
  const double mid = filament_mm_ + 0.5 * dt_s * rate(filament_mm_);
  const double q_mm3_s = rate(mid) * area_mm2_;
  filament_mm_ += dt_s * q_mm3_s / area_mm2_;
  force_n_ = std::max(0.0, p_.stiffness_n_per_mm * (play_out_mm_ - filament_mm_));
  // Melt-flow lag to the nozzle exit (exact for q held over the step).
  const double a = p_.melt_lag_s > 0.0 ? 1.0 - std::exp(-dt_s / p_.melt_lag_s) : 1.0;
  const double q_prev = q_noz_mm3_s_;
  q_noz_mm3_s_ += (q_mm3_s - q_noz_mm3_s_) * a;
  volume_mm3_ += 0.5 * (q_prev + q_noz_mm3_s_) * dt_s;
}

double ExtruderPlant::time_constant_s(double flow_mm3_s) const {
  if (flow_mm3_s <= 0.0) return 0.0;
  const double p0 = std::pow(flow_mm3_s / c_, 1.0 / p_.flow_exponent);
  return area_mm2_ * area_mm2_ * p0 / (p_.stiffness_n_per_mm * p_.flow_exponent * flow_mm3_s);
}

}  // namespace feedloop::sim
