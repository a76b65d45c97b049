// Thermal plant of one heater for the simulated printer (docs/simulator.md, "Thermal plant"):
// the heater block as a first-order lag with a transport delay, losses to ambient (natural
// convection plus the part fan's forced cooling), a thermistor with its own lag in a divider read
// by a 12-bit ADC with noise, and the faults to inject. Implements device::HeaterPort.
//
//   C dT_b/dt = eta * P * u(t - delay_s) - (h + h_fan * fan) (T_b - T_amb)
//   dT_s/dt = (T_b - T_s) / sensor_tau_s            (the sensor lags the block)
//
// The host's PID knows none of this (it sees only the ADC): delay, sensor lag, fan cooling, ADC
// quantisation and noise are the effects its model lacks.
#pragma once

#include <cstdint>
#include <deque>

#include "core/rng.hpp"
#include "drivers/device/heater_port.hpp"
#include "thermal/sensor.hpp"

namespace feedloop::sim {

struct ThermalPlantParams {
  double power_w = 40.0;            // heater cartridge
  double heat_capacity_j_k = 12.0;  // block + nozzle
  double loss_w_k = 0.065;          // to ambient, natural convection
  double fan_loss_w_k = 0.05;       // extra loss with the part fan at full duty
  double delay_s = 1.0;             // heater -> block transport delay
  double sensor_tau_s = 1.5;        // thermistor lag
  double ambient_c = 22.0;
  double adc_noise_lsb = 1.5;  // of a 12-bit converter (1 LSB = 16 of the 65535 full scale)
  double step_s = 0.01;        // integration step
  uint64_t seed = 1;
  thermal::SensorParams sensor = *thermal::builtin_sensor("Semitec 104GT-2");
};

enum class ThermalFaultKind : uint8_t {
  kNone,
  kThermistorOpen,
  kThermistorShort,
  kHeaterOutOfBlock,
  kHeaterStuckOn,
  kSensorStuck,
};
const char* to_string(ThermalFaultKind k);

class ThermalPlant final : public device::HeaterPort {
 public:
  explicit ThermalPlant(const ThermalPlantParams& p);
  void set_duty(double t_s, double duty) override;
  uint16_t read_adc(double t_s) override;
  // Advances the physics to t_s (read_adc and set_duty do it too).
  void advance(double t_s);
  void set_fan(double t_s, double duty);
  void inject(double t_s, ThermalFaultKind k);
  double block_temp_c() const { return block_c_; }
  double sensor_temp_c() const { return sensor_c_; }
  double duty() const { return duty_; }
  double time_s() const { return t_s_; }
  ThermalFaultKind fault() const { return fault_; }
  const ThermalPlantParams& params() const { return p_; }

 private:
  double delayed_power_w(double t_s);
  ThermalPlantParams p_;
  Rng rng_;
  double t_s_ = 0.0, block_c_, sensor_c_, duty_ = 0.0, fan_ = 0.0;
  struct DutyChange {
    double t_s;
    double duty;
  };
  std::deque<DutyChange> history_;  // duty changes within the delay window
  double delayed_duty_ = 0.0;
  ThermalFaultKind fault_ = ThermalFaultKind::kNone;
  uint16_t stuck_adc_ = 0;
};

// A fan that also cools the plants it blows on.
class PartFan final : public device::FanPort {
 public:
  void attach(ThermalPlant* p) {
    if (n_ < 4) plants_[n_++] = p;
  }
  void set_duty(double t_s, double duty) override {
    duty_ = duty;
    for (int i = 0; i < n_; ++i) plants_[i]->set_fan(t_s, duty);
  }
  double duty() const { return duty_; }

 private:
  ThermalPlant* plants_[4] = {};
  int n_ = 0;
  double duty_ = 0.0;
};

}  // namespace feedloop::sim
