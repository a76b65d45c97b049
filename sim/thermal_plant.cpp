#include "sim/thermal_plant.hpp"

#include <algorithm>
#include <cmath>

namespace feedloop::sim {

const char* to_string(ThermalFaultKind k) {
  switch (k) {
    case ThermalFaultKind::kNone:
      return "none";
    case ThermalFaultKind::kThermistorOpen:
      return "thermistor_open";
    case ThermalFaultKind::kThermistorShort:
      return "thermistor_short";
    case ThermalFaultKind::kHeaterOutOfBlock:
      return "heater_out_of_block";
    case ThermalFaultKind::kHeaterStuckOn:
      return "heater_stuck_on";
    case ThermalFaultKind::kSensorStuck:
      return "sensor_stuck";
  }
  return "unknown";
}

ThermalPlant::ThermalPlant(const ThermalPlantParams& p)
    : p_(p), rng_(p.seed), block_c_(p.ambient_c), sensor_c_(p.ambient_c) {}

double ThermalPlant::delayed_power_w(double t_s) {
  // The duty in force at t_s - delay_s.
  const double tq = t_s - p_.delay_s;
  while (!history_.empty() && history_.front().t_s <= tq) {
    delayed_duty_ = history_.front().duty;
    history_.pop_front();
  }
  double u = delayed_duty_;
  if (fault_ == ThermalFaultKind::kHeaterStuckOn) u = 1.0;
  // Out of its block, the cartridge heats the air around it, not the block.
  const double eta = fault_ == ThermalFaultKind::kHeaterOutOfBlock ? 0.0 : 1.0;
  return eta * u * p_.power_w;
}

void ThermalPlant::advance(double t_s) {
  while (t_s_ + 1e-12 < t_s) {
    const double dt = std::min(p_.step_s, t_s - t_s_);
    const double pw = delayed_power_w(t_s_);
    const double loss = (p_.loss_w_k + p_.fan_loss_w_k * fan_) * (block_c_ - p_.ambient_c);
    block_c_ += dt * (pw - loss) / p_.heat_capacity_j_k;
    sensor_c_ += (block_c_ - sensor_c_) * (1.0 - std::exp(-dt / p_.sensor_tau_s));
    t_s_ += dt;
  }
}

void ThermalPlant::set_duty(double t_s, double duty) {
  advance(t_s);
  duty = std::clamp(duty, 0.0, 1.0);
  if (duty != duty_) history_.push_back({t_s, duty});
  duty_ = duty;
}

void ThermalPlant::set_fan(double t_s, double duty) {
  advance(t_s);
  fan_ = std::clamp(duty, 0.0, 1.0);
}

void ThermalPlant::inject(double t_s, ThermalFaultKind k) {
  advance(t_s);
  if (k == ThermalFaultKind::kSensorStuck) stuck_adc_ = read_adc(t_s);
  fault_ = k;
}

uint16_t ThermalPlant::read_adc(double t_s) {
  advance(t_s);
  switch (fault_) {
    case ThermalFaultKind::kThermistorOpen:
      return 65535;
    case ThermalFaultKind::kThermistorShort:
      return 0;
    case ThermalFaultKind::kSensorStuck:
      return stuck_adc_;
    default:
      break;
  }
  const double frac = thermal::adc_at(p_.sensor, sensor_c_);
  // 12-bit conversion with noise, scaled to the 16-bit full scale of the protocol.
  const double code = std::round(frac * 4095.0 + rng_.gaussian() * p_.adc_noise_lsb);
  return static_cast<uint16_t>(std::clamp(code, 0.0, 4095.0) * 16.0);
}

}  // namespace feedloop::sim
