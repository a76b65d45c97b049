#include "engine/thermal_config.hpp"

#include "engine/mcu_transport.hpp"
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

BoardChannels board_channels(const config::MachineConfig& cfg, const std::string& board) {
  BoardChannels c;
  for (size_t i = 0; i < cfg.heaters.size(); ++i)
    if (cfg.heaters[i].mcu == board) c.heaters.push_back(static_cast<int>(i));
  for (size_t i = 0; i < cfg.fans.size(); ++i)
    if (cfg.fans[i].mcu == board) c.fans.push_back(static_cast<int>(i));
  return c;
}

namespace {

// heater_mcus: one McuHeaterLink MCU per board that drives a heater or a fan; its heaters and
// fans take its channels in file order. Mock boards are simulated in-process.
Result<std::unique_ptr<HeaterLink>> make_board_heater_link(const config::MachineConfig& cfg,
                                                           double host_hz,
                                                           const SharedHeaterPorts* ports) {
  // (The loader refuses a heater or fan without a board; hand-built configs get the same.)
  for (const config::HeaterConfig& h : cfg.heaters)
    if (h.mcu.empty()) return Error{"heater '" + h.name + "' names no board (mcu:)"};
  for (const config::FanConfig& f : cfg.fans)
    if (f.mcu.empty()) return Error{"fan '" + f.name + "' names no board (mcu:)"};
  std::vector<HeaterMcu> mcus;
  std::vector<HeaterRoute> hr(cfg.heaters.size()), fr(cfg.fans.size());
  // The boards: heater_mcus first, then the motion MCUs that drive heaters too.
  std::vector<const config::McuConfig*> boards;
  for (const config::McuConfig& b : cfg.heater_mcus) boards.push_back(&b);
  for (const config::McuConfig& b : cfg.mcus) boards.push_back(&b);
  for (size_t b = 0; b < boards.size(); ++b) {
    const config::McuConfig& board = *boards[b];
    const bool motion_mcu = b >= cfg.heater_mcus.size();
    const auto [heaters, fans] = board_channels(cfg, board.name);
    if (heaters.empty() && fans.empty()) continue;  // nothing on it: not opened
    if (heaters.size() > 4 || fans.size() > 4)
      return Error{"heater MCU '" + board.name + "': at most 4 heaters and 4 fans per board"};
    const int index = static_cast<int>(mcus.size());
    for (size_t k = 0; k < heaters.size(); ++k)
      hr[static_cast<size_t>(heaters[k])] = {index, static_cast<uint8_t>(k)};
    for (size_t k = 0; k < fans.size(); ++k)
      fr[static_cast<size_t>(fans[k])] = {index, static_cast<uint8_t>(k)};
    if (motion_mcu) {  // its session is the motion bridge's (servo thread): through its port
      HeaterMcu m;
      m.name = board.name;
      if (ports != nullptr)
        for (const auto& p : *ports)
          if (p && p->mcu_name() == board.name) m.shared = p;
      if (!m.shared)
        return Error{"heaters on motion MCU '" + board.name +
                     "' go through its session in the motion bridge: build the thermal loop with "
                     "the executor's heater_ports()"};
      mcus.push_back(std::move(m));
      continue;
    }
    if (board.transport == config::TransportType::mock) {
      mcus.push_back(simulated_heater_mcu(cfg, heaters, fans, static_cast<double>(board.clock_hz),
                                          board.name, cfg.simulator.seed + 9500 + 7919 * b));
      continue;
    }
    HeaterMcu m;
    m.name = board.name;
    m.transport = make_hardware_transport(board, 0);  // not real-time: the thermal thread's pace
    m.session = heater_session_params(board.name);
    mcus.push_back(std::move(m));
  }
  return std::unique_ptr<HeaterLink>(
      std::make_unique<McuHeaterLink>(std::move(mcus), std::move(hr), std::move(fr), host_hz));
}

}  // namespace

bool heaters_on_boards(const config::MachineConfig& cfg) {
  if (!cfg.heater_mcus.empty()) return true;
  for (const config::McuConfig& m : cfg.mcus)
    if (!board_channels(cfg, m.name).empty()) return true;
  return false;
}

Result<std::unique_ptr<ThermalLoop>> make_thermal_loop(const config::MachineConfig& cfg,
                                                       const SharedHeaterPorts* ports) {
  if (cfg.heaters.empty() && cfg.fans.empty()) return std::unique_ptr<ThermalLoop>();
  const ThermalOptions o = thermal_options(cfg);
  if (heaters_on_boards(cfg)) {
    auto link = make_board_heater_link(cfg, o.mcu_clock_hz, ports);
    if (!link.ok()) return link.error();
    return std::make_unique<ThermalLoop>(o, std::move(link.value()));
  }
  for (const config::McuConfig& m : cfg.mcus)
    if (m.transport != config::TransportType::mock)
      return Error{
          "the heaters and fans have no board: without heater_mcus they run on the simulated "
          "printer's heater board, which needs every MCU simulated (mcu '" +
          m.name +
          "' is not mock); name the board in each heater's and fan's mcu: (a motion MCU, or a "
          "board of heater_mcus; config/README.md), or remove the heaters: and fans: sections"};
  return std::make_unique<ThermalLoop>(o, make_simulated_heater_link(cfg, o.mcu_clock_hz));
}

}  // namespace feedloop::engine
