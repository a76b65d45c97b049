// Config sections `heaters` and `fans` (docs/heaters.md): one mapping per heater / fan, keyed by
// its name. Plausibility: max_temp_c within the kind's range, min_temp_c below it, the sensor able
// to tell max_temp_c and min_temp_c from a short and an open circuit through its divider, a heater
// fan's heater defined.
#include <cmath>

#include "config/enum_names.hpp"
#include "config/sections.hpp"
#include "thermal/protection.hpp"
#include "thermal/sensor.hpp"

namespace feedloop::config::detail {
namespace {

double kind_max_temp_c(HeaterKind k) {
  switch (k) {
    case HeaterKind::extruder:
      return 500.0;  // all-metal hotends with a PT1000
    case HeaterKind::bed:
      return 150.0;
    case HeaterKind::chamber:
      return 100.0;
  }
  return 500.0;
}

void read_heater(MapReader& m, HeaterConfig& h, Diagnostics& diag) {
  m.choice("kind", h.kind, heater_kind_names(), Need::required);
  if (h.kind == HeaterKind::bed) {  // Marlin's bed defaults
    h.max_temp_c = 120.0;
    h.pid_kp = 97.1;
    h.pid_ki = 1.41;
    h.pid_kd = 1675.16;
    h.protection.watch_period_s = 60.0;  // Marlin WATCH_BED_TEMP_PERIOD / INCREASE
    h.protection.watch_increase_c = 2.0;
    h.protection.runaway_period_s = 20.0;  // THERMAL_PROTECTION_BED_PERIOD / HYSTERESIS
    h.protection.runaway_hysteresis_c = 2.0;
    h.protection.verify_gain_time_s = 60.0;  // Klipper's bed default check_gain_time
    h.plant = HeaterPlantConfig{250.0, 350.0, 1.2, 0.1, 3.0, 3.0, 22.0};
  }
  m.string("sensor", h.sensor);
  m.number("pullup_ohm", h.pullup_ohm, Range::positive());
  if (m.has("thermistor")) {
    MapReader t = m.sub("thermistor");
    ThermistorConfig tc;
    t.choice("form", tc.form, thermistor_form_names(), Need::required);
    t.number("t1_c", tc.t1_c, Range::open(-273.15, 1000.0));
    t.number("r1_ohm", tc.r1_ohm, Range::positive());
    if (tc.form == ThermistorConfig::Form::beta) {
      t.number("beta", tc.beta, Range::positive(), Need::required);
    } else {
      t.number("t2_c", tc.t2_c, Range::open(-273.15, 1000.0), Need::required);
      t.number("r2_ohm", tc.r2_ohm, Range::positive(), Need::required);
      t.number("t3_c", tc.t3_c, Range::open(-273.15, 1000.0), Need::required);
      t.number("r3_ohm", tc.r3_ohm, Range::positive(), Need::required);
    }
    t.finish();
    h.thermistor = tc;
  } else {
    m.sub("thermistor");
  }
  m.number("min_temp_c", h.min_temp_c, Range::closed(-50.0, 500.0));
  const double kind_max = kind_max_temp_c(h.kind);
  if (m.number("max_temp_c", h.max_temp_c, Range::open_closed(0.0, 1000.0)) &&
      h.max_temp_c > kind_max)
    diag.add(m.get("max_temp_c").Mark(), m.key_path("max_temp_c") + " = " +
                                             format_number(h.max_temp_c) +
                                             " C is implausible for a heater of kind " +
                                             enum_name(heater_kind_names(), h.kind) + " (at most " +
                                             format_number(kind_max) + " C)");
  if (h.min_temp_c >= h.max_temp_c)
    diag.add(m.key_mark("min_temp_c"), m.key_path("min_temp_c") + " must be below max_temp_c (" +
                                           format_number(h.max_temp_c) + " C)");
  m.number("max_power", h.max_power, Range::open_closed(0.0, 1.0));
  m.number("residency_s", h.residency_s, Range::closed(0.0, 120.0));
  MapReader pid = m.sub("pid");
  pid.number("kp", h.pid_kp, Range::positive());
  pid.number("ki", h.pid_ki, Range::non_negative());
  pid.number("kd", h.pid_kd, Range::non_negative());
  pid.finish();
  MapReader pr = m.sub("protection");
  HeaterProtectionConfig& p = h.protection;
  pr.number("watch_period_s", p.watch_period_s, Range::non_negative());
  pr.number("watch_increase_c", p.watch_increase_c, Range::positive());
  pr.number("runaway_period_s", p.runaway_period_s, Range::non_negative());
  pr.number("runaway_hysteresis_c", p.runaway_hysteresis_c, Range::positive());
  pr.number("verify_max_error", p.verify_max_error, Range::non_negative());
  pr.number("verify_gain_time_s", p.verify_gain_time_s, Range::positive());
  pr.number("verify_hysteresis_c", p.verify_hysteresis_c, Range::positive());
  pr.number("verify_heating_gain_c", p.verify_heating_gain_c, Range::positive());
  pr.number("stuck_period_s", p.stuck_period_s, Range::non_negative());
  pr.finish();
  MapReader pl = m.sub("plant");
  pl.number("power_w", h.plant.power_w, Range::positive());
  pl.number("heat_capacity_j_k", h.plant.heat_capacity_j_k, Range::positive());
  pl.number("loss_w_k", h.plant.loss_w_k, Range::positive());
  pl.number("fan_loss_w_k", h.plant.fan_loss_w_k, Range::non_negative());
  pl.number("delay_s", h.plant.delay_s, Range::closed(0.0, 60.0));
  pl.number("sensor_tau_s", h.plant.sensor_tau_s, Range::positive());
  pl.number("ambient_c", h.plant.ambient_c, Range::closed(-20.0, 60.0));
  pl.finish();

  // The sensor: known, and able to read the whole range through its divider.
  std::optional<thermal::SensorParams> sp;
  if (h.sensor == "thermistor") {
    if (!h.thermistor) {
      diag.add(m.key_mark("sensor"),
               m.key_path("sensor") + ": thermistor needs a thermistor: mapping");
      return;
    }
    const ThermistorConfig& t = *h.thermistor;
    sp = t.form == ThermistorConfig::Form::beta
             ? thermal::beta_thermistor(t.t1_c, t.r1_ohm, t.beta, h.pullup_ohm)
             : thermal::steinhart_hart(t.t1_c, t.r1_ohm, t.t2_c, t.r2_ohm, t.t3_c, t.r3_ohm,
                                       h.pullup_ohm);
    if (!sp) {
      diag.add(m.key_mark("thermistor"),
               m.key_path("thermistor") +
                   ": these points give no usable curve (the resistance must fall "
                   "as the temperature rises)");
      return;
    }
  } else {
    sp = thermal::builtin_sensor(h.sensor, h.pullup_ohm);
    if (!sp) {
      diag.add(m.get("sensor").IsDefined() ? m.get("sensor").Mark() : m.mark(),
               m.key_path("sensor") + ": unknown sensor '" + h.sensor +
                   "' (known: Semitec 104GT-2, EPCOS 100K B57560G104F, PT1000, thermistor)");
      return;
    }
  }
  const thermal::ProtectionParams defaults;
  for (const double t : {h.min_temp_c, h.max_temp_c}) {
    const double adc = thermal::adc_at(*sp, t);
    if (!(adc > defaults.short_adc && adc < defaults.open_adc))
      diag.add(m.key_mark(t == h.max_temp_c ? "max_temp_c" : "min_temp_c"),
               m.path() + ": sensor '" + h.sensor + "' with pullup_ohm " +
                   format_number(h.pullup_ohm) + " reads " + format_number(t) +
                   " C as an ADC fraction of " + format_number(std::round(adc * 1e4) / 1e4) +
                   ", indistinguishable from a " +
                   (adc <= defaults.short_adc ? "short" : "broken wire") +
                   "; narrow the temperature range or choose another sensor/pullup");
  }
}

}  // namespace

namespace {

// heater_mcus: the boards that drive heaters and fans (name, transport, clock_hz; no axes).
void read_heater_mcus(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  if (!root.has("heater_mcus")) {
    root.get("heater_mcus");
    return;
  }
  const YAML::Node list = root.get("heater_mcus");
  if (!list.IsSequence() || list.size() == 0) {
    diag.add(list.Mark(), "heater_mcus must be a non-empty list of boards, got " + node_kind(list));
    return;
  }
  for (std::size_t i = 0; i < list.size(); ++i) {
    MapReader m(list[i], "heater_mcus[" + std::to_string(i) + "]", diag, list[i].Mark());
    if (!m.present()) continue;
    McuConfig mcu;
    mcu.clock_hz = cfg.stepgen.mcu_clock_hz;
    if (m.string("name", mcu.name, Need::required)) {
      bool taken = mcu.name.empty();
      for (const McuConfig& o : cfg.heater_mcus) taken = taken || o.name == mcu.name;
      for (const McuConfig& o : cfg.mcus) taken = taken || o.name == mcu.name;
      if (taken)
        diag.add(m.key_mark("name"), m.key_path("name") + ": '" + mcu.name +
                                         "' is empty or already names an mcu (names are unique "
                                         "across mcus and heater_mcus)");
    }
    read_transport(m, mcu, diag);
    m.integer("clock_hz", mcu.clock_hz, 1000000, 2000000000);
    m.finish();
    cfg.heater_mcus.push_back(mcu);
  }
}

// A heater's or fan's `mcu:` names its board: a heater_mcus entry, or a motion MCU of mcus (one
// board for motion and heaters). With heater_mcus given, each needs one; so it does when another
// heater or fan names a board (checked once all are read: board_refs_complete).
void read_board_ref(MapReader& m, const MachineConfig& cfg, std::string& mcu, Diagnostics& diag) {
  if (!m.string("mcu", mcu, cfg.heater_mcus.empty() ? Need::optional : Need::required)) return;
  bool found = false;
  for (const McuConfig& b : cfg.heater_mcus) found = found || b.name == mcu;
  for (const McuConfig& b : cfg.mcus) found = found || b.name == mcu;
  if (found) return;
  diag.add(m.get("mcu").Mark(), m.key_path("mcu") + ": no MCU named '" + mcu +
                                    "' (a heater's board is a motion MCU of mcus or a board of "
                                    "heater_mcus)");
  mcu.clear();  // one error, not one more for each heater without a board
}

// Without heater_mcus a board is optional, but all or none: a heater on a motion MCU beside one
// on the simulated printer's heater board is no machine.
void board_refs_complete(const std::vector<std::pair<std::string, YAML::Mark>>& missing,
                         bool any_named, Diagnostics& diag) {
  if (!any_named) return;
  for (const auto& [what, mark] : missing)
    diag.add(mark, what +
                       ": names no board (mcu:) while others do: give every heater and fan its "
                       "board");
}

}  // namespace

void read_thermal(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  read_heater_mcus(root, cfg, diag);
  std::vector<std::pair<std::string, YAML::Mark>> missing;  // heaters and fans without mcu:
  MapReader heaters = root.sub("heaters");
  for (const std::string& name : heaters.keys()) {
    MapReader m = heaters.sub(name);
    HeaterConfig h;
    h.name = name;
    if (name.size() > 15)
      diag.add(heaters.key_mark(name), "heater name '" + name + "' is longer than 15 characters");
    read_heater(m, h, diag);
    read_board_ref(m, cfg, h.mcu, diag);
    if (h.mcu.empty()) missing.emplace_back("heaters." + name, heaters.key_mark(name));
    m.finish();
    cfg.heaters.push_back(h);
  }
  if (cfg.heaters.size() > 4) diag.add(heaters.mark(), "at most 4 heaters are supported");
  heaters.finish();

  MapReader fans = root.sub("fans");
  for (const std::string& name : fans.keys()) {
    MapReader m = fans.sub(name);
    FanConfig f;
    f.name = name;
    if (name.size() > 15)
      diag.add(fans.key_mark(name), "fan name '" + name + "' is longer than 15 characters");
    m.choice("kind", f.kind, fan_kind_names(), Need::required);
    if (f.kind == FanKind::heater) {
      if (m.string("heater", f.heater, Need::required)) {
        bool found = false;
        for (const HeaterConfig& h : cfg.heaters) found = found || h.name == f.heater;
        if (!found)
          diag.add(m.get("heater").Mark(),
                   m.key_path("heater") + ": no heater named '" + f.heater + "'");
      }
      m.number("heater_temp_c", f.heater_temp_c, Range::closed(0.0, 200.0));
    }
    m.number("kick_start_s", f.kick_start_s, Range::closed(0.0, 5.0));
    m.number("off_below", f.off_below, Range::closed(0.0, 1.0));
    m.number("max_power", f.max_power, Range::open_closed(0.0, 1.0));
    read_board_ref(m, cfg, f.mcu, diag);
    if (f.mcu.empty()) missing.emplace_back("fans." + name, fans.key_mark(name));
    m.finish();
    cfg.fans.push_back(f);
  }
  if (cfg.fans.size() > 4) diag.add(fans.mark(), "at most 4 fans are supported");
  fans.finish();
  bool any_named = false;
  for (const HeaterConfig& h : cfg.heaters) any_named = any_named || !h.mcu.empty();
  for (const FanConfig& f : cfg.fans) any_named = any_named || !f.mcu.empty();
  board_refs_complete(missing, any_named && cfg.heater_mcus.empty(), diag);
}

}  // namespace feedloop::config::detail
