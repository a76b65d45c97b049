#include "engine/thermal_config.hpp"

#include "engine/simulated_printer.hpp"

namespace feedloop::engine {

thermal::SensorParams heater_sensor(const config::HeaterConfig& h) {
  std::optional<thermal::SensorParams> s;
  if (h.sensor == "thermistor" && h.thermistor) {
    const config::ThermistorConfig& t = *h.thermistor;
    s = t.form == config::ThermistorConfig::Form::beta
            ? thermal::beta_thermistor(t.t1_c, t.r1_ohm, t.beta, h.pullup_ohm)
            : thermal::steinhart_hart(t.t1_c, t.r1_ohm, t.t2_c, t.r2_ohm, t.t3_c, t.r3_ohm,
                                      h.pullup_ohm);
  } else {
    s = thermal::builtin_sensor(h.sensor, h.pullup_ohm);
  }
  // The loader refused anything else; keep a sane fallback for hand-built configs.
  return s ? *s : *thermal::builtin_sensor("EPCOS 100K B57560G104F", h.pullup_ohm);
}

ThermalOptions thermal_options(const config::MachineConfig& cfg) {
  ThermalOptions o;
  for (const config::HeaterConfig& h : cfg.heaters) {
    HeaterSpec s;
    s.name = h.name;
    s.marlin = h.kind == config::HeaterKind::bed       ? 'B'
               : h.kind == config::HeaterKind::chamber ? 'C'
                                                       : 'T';
    s.sensor = heater_sensor(h);
    s.residency_s = h.residency_s;
    s.pid = thermal::PidParams{h.pid_kp, h.pid_ki, h.pid_kd, h.max_power, 1.0};
    thermal::ProtectionParams& p = s.protection;
    p.min_temp_c = h.min_temp_c;
    p.max_temp_c = h.max_temp_c;
    p.watch_period_s = h.protection.watch_period_s;
    p.watch_increase_c = h.protection.watch_increase_c;
    p.runaway_period_s = h.protection.runaway_period_s;
    p.runaway_hysteresis_c = h.protection.runaway_hysteresis_c;
    p.verify_max_error_cs = h.protection.verify_max_error;
    p.verify_gain_time_s = h.protection.verify_gain_time_s;
    p.verify_hysteresis_c = h.protection.verify_hysteresis_c;
    p.verify_heating_gain_c = h.protection.verify_heating_gain_c;
    p.stuck_period_s = h.protection.stuck_period_s;
    o.heaters.push_back(s);
  }
  for (const config::FanConfig& f : cfg.fans) {
    FanSpec s;
    s.name = f.name;
    s.kind = f.kind == config::FanKind::heater ? FanSpec::Kind::kHeater : FanSpec::Kind::kPart;
    for (size_t i = 0; i < cfg.heaters.size(); ++i)
      if (cfg.heaters[i].name == f.heater) s.heater = static_cast<int>(i);
    s.heater_temp_c = f.heater_temp_c;
    s.kick_start_s = f.kick_start_s;
    s.off_below = f.off_below;
    s.max_power = f.max_power;
    o.fans.push_back(s);
  }
  o.mcu_clock_hz = 1e6;
  return o;
}

Result<std::unique_ptr<ThermalLoop>> make_thermal_loop(const config::MachineConfig& cfg) {
  if (cfg.heaters.empty() && cfg.fans.empty()) return std::unique_ptr<ThermalLoop>();
  for (const config::McuConfig& m : cfg.mcus)
    if (m.transport != config::TransportType::mock)
      return Error{"heaters and fans run only on the simulated printer's heater MCU so far (mcu '" +
                   m.name + "' is not mock, and heaters on a motion MCU's link are not wired: "
                   "docs/heaters.md); remove the heaters: and fans: sections"};
  const ThermalOptions o = thermal_options(cfg);
  return std::make_unique<ThermalLoop>(o, make_simulated_heater_link(cfg, o.mcu_clock_hz));
}

}  // namespace feedloop::engine
