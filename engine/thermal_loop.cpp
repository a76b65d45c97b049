#include "engine/thermal_loop.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "drivers/protocol/heater_messages.hpp"

namespace feedloop::engine {

namespace {
uint16_t to_u16(double frac) {
  return static_cast<uint16_t>(std::lround(std::clamp(frac, 0.0, 1.0) * 65535.0));
}
}  // namespace

ThermalLoop::ThermalLoop(ThermalOptions options, std::unique_ptr<HeaterLink> link)
    : opt_(std::move(options)), link_(std::move(link)) {
  if (opt_.heaters.size() > kMaxHeaters) opt_.heaters.resize(kMaxHeaters);
  if (opt_.fans.size() > kMaxFans) opt_.fans.resize(kMaxFans);
  for (const HeaterSpec& s : opt_.heaters) {
    Heater h;
    h.pid = thermal::HeaterPid(s.pid);
    h.protection = thermal::ThermalProtection(s.protection);
    h_.push_back(std::move(h));
  }
  f_.resize(opt_.fans.size());
}

void ThermalLoop::start(double now_s) {
  std::lock_guard lock(mu_);
  now_s_ = now_s;
  double grace_s = 0.0;
  for (const HeaterSpec& s : opt_.heaters) grace_s = std::max(grace_s, s.report_grace_s);
  reports_due_from_s_ = now_s + grace_s;
  for (size_t i = 0; i < h_.size(); ++i) {
    const HeaterSpec& s = opt_.heaters[i];
    // The MCU's own range: the ADC values of min_temp and max_temp (an NTC reads lower when hotter,
    // a PT1000 higher), Klipper's analog-in min/max check on the MCU.
    const double a_lo = thermal::adc_at(s.sensor, s.protection.min_temp_c);
    const double a_hi = thermal::adc_at(s.sensor, s.protection.max_temp_c);
    protocol::ConfigureHeaterMsg m;
    m.heater = static_cast<uint8_t>(i);
    const double sample_s = s.report_period_s / std::max(1, s.oversample);
    m.sample_period_ticks = static_cast<uint32_t>(std::max(1.0, sample_s * opt_.mcu_clock_hz));
    m.samples_per_report = static_cast<uint16_t>(std::max(1, s.oversample));
    m.adc_min = to_u16(std::min(a_lo, a_hi));
    m.adc_max = to_u16(std::max(a_lo, a_hi));
    m.confirm_timeout_ticks = static_cast<uint32_t>(s.confirm_timeout_s * opt_.mcu_clock_hz);
    m.max_duty = to_u16(s.pid.max_power);
    uint8_t buf[32];
    if (const size_t n = protocol::encode_configure_heater(m, buf, sizeof buf))
      link_->send(now_s, buf, n);
  }
  for (size_t i = 0; i < f_.size(); ++i) send_fan(static_cast<int>(i), 0.0, now_s);
}

int ThermalLoop::find_heater(char marlin, int tool) const {
  int seen = 0;
  for (size_t i = 0; i < opt_.heaters.size(); ++i)
    if (opt_.heaters[i].marlin == marlin && seen++ == tool) return static_cast<int>(i);
  return -1;
}

Status ThermalLoop::set_target(int heater, double target_c) {
  std::lock_guard lock(mu_);
  if (heater < 0 || heater >= static_cast<int>(h_.size())) return Error{"no such heater"};
  const HeaterSpec& s = opt_.heaters[static_cast<size_t>(heater)];
  if (target_c > s.protection.max_temp_c) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "heater %s: target %.1f C is above its max_temp_c %.1f C",
                  s.name.c_str(), target_c, s.protection.max_temp_c);
    return Error{buf};
  }
  if (fault_ && target_c > 0)
    return Error{"heater " + s.name + " is off after a thermal fault (" + *fault_ + "); send M999"};
  Heater& h = h_[static_cast<size_t>(heater)];
  if (target_c != h.target_c) h.in_window_since_s = -1.0;
  h.target_c = std::max(0.0, target_c);
  if (h.target_c == 0.0) send_heater(heater, 0.0, now_s_);
  update_heater_fans(now_s_);
  return Status::Ok();
}

double ThermalLoop::target_c(int heater) const {
  std::lock_guard lock(mu_);
  return h_[static_cast<size_t>(heater)].target_c;
}
// NaN until the heater's first report: "0 C" before it would read as a frozen hotend.
double ThermalLoop::temp_c(int heater) const {
  std::lock_guard lock(mu_);
  const Heater& h = h_[static_cast<size_t>(heater)];
  return h.have_temp ? h.temp_c : std::numeric_limits<double>::quiet_NaN();
}

bool ThermalLoop::reached(int heater, bool heating_only, double now_s) {
  std::lock_guard lock(mu_);
  Heater& h = h_[static_cast<size_t>(heater)];
  const HeaterSpec& s = opt_.heaters[static_cast<size_t>(heater)];
  if (h.target_c <= 0.0) return true;
  if (!h.have_temp) return false;
  const double err = h.temp_c - h.target_c;
  // Marlin: the residency timer starts within TEMP_WINDOW and restarts beyond TEMP_HYSTERESIS.
  const bool inside = std::fabs(err) <= s.window_c || (heating_only && err > 0);
  if (h.in_window_since_s < 0) {
    if (inside) h.in_window_since_s = now_s;
  } else if (std::fabs(err) > s.hysteresis_c && !(heating_only && err > 0)) {
    h.in_window_since_s = -1.0;
  }
  return h.in_window_since_s >= 0 && now_s - h.in_window_since_s >= s.residency_s;
}

void ThermalLoop::send_heater(int i, double power, double now_s) {
  uint8_t buf[32];
  const size_t n =
      protocol::encode_set_heater({static_cast<uint8_t>(i), to_u16(power)}, buf, sizeof buf);
  if (n) link_->send(now_s, buf, n);
  h_[static_cast<size_t>(i)].power = power;
}

void ThermalLoop::send_fan(int i, double speed, double now_s) {
  uint8_t buf[32];
  const size_t n =
      protocol::encode_set_fan({static_cast<uint8_t>(i), to_u16(speed)}, buf, sizeof buf);
  if (n) link_->send(now_s, buf, n);
  f_[static_cast<size_t>(i)].speed = speed;
}

Status ThermalLoop::set_fan(int part_fan, double speed, double now_s) {
  std::lock_guard lock(mu_);
  int seen = 0;
  for (size_t i = 0; i < f_.size(); ++i) {
    const FanSpec& s = opt_.fans[i];
    if (s.kind != FanSpec::Kind::kPart || seen++ != part_fan) continue;
    Fan& f = f_[i];
    double v = std::clamp(speed, 0.0, 1.0) * s.max_power;
    if (v < s.off_below) v = 0.0;
    f.requested = v;
    // Klipper's fan.py: a kick at full power when starting from off or jumping up by more than
    // half.
    if (s.kick_start_s > 0 && v > 0 && v < 1.0 && (f.speed == 0.0 || v - f.speed > 0.5)) {
      f.kick_until_s = now_s + s.kick_start_s;
      send_fan(static_cast<int>(i), s.max_power, now_s);
    } else {
      f.kick_until_s = -1.0;
      send_fan(static_cast<int>(i), v, now_s);
    }
    return Status::Ok();
  }
  return Error{"no part fan " + std::to_string(part_fan)};
}

void ThermalLoop::update_heater_fans(double now_s) {
  for (size_t i = 0; i < f_.size(); ++i) {
    const FanSpec& s = opt_.fans[i];
    Fan& f = f_[i];
    if (s.kind == FanSpec::Kind::kPart) {
      if (f.kick_until_s >= 0 && now_s >= f.kick_until_s) {
        f.kick_until_s = -1.0;
        send_fan(static_cast<int>(i), f.requested, now_s);
      }
      continue;
    }
    if (s.heater < 0 || s.heater >= static_cast<int>(h_.size())) continue;
    const Heater& h = h_[static_cast<size_t>(s.heater)];
    // Klipper heater_fan: on while the heater has a target or is above heater_temp.
    const double want = (h.target_c > 0 || h.temp_c > s.heater_temp_c) ? s.max_power : 0.0;
    if (want != f.speed) send_fan(static_cast<int>(i), want, now_s);
  }
}

void ThermalLoop::trip(int i, const std::string& why, double now_s) {
  if (!fault_) fault_ = "heater " + opt_.heaters[static_cast<size_t>(i)].name + ": " + why;
  h_[static_cast<size_t>(i)].faulted = true;
  for (size_t k = 0; k < h_.size(); ++k) {  // every heater off
    h_[k].target_c = 0.0;
    h_[k].autotune.reset();
    send_heater(static_cast<int>(k), 0.0, now_s);
  }
  if (autotune_heater_ >= 0 && !autotune_result_)
    autotune_result_ = Error{"autotune stopped: " + *fault_};
}

void ThermalLoop::all_off(double now_s) {
  std::lock_guard lock(mu_);
  for (size_t k = 0; k < h_.size(); ++k) {
    h_[k].target_c = 0.0;
    h_[k].autotune.reset();
    send_heater(static_cast<int>(k), 0.0, now_s);
  }
}

std::optional<std::string> ThermalLoop::fault() const {
  std::lock_guard lock(mu_);
  return fault_;
}

void ThermalLoop::clear_fault() {
  std::lock_guard lock(mu_);
  fault_.reset();
  fault_reported_ = false;
  for (size_t i = 0; i < h_.size(); ++i) {
    h_[i].faulted = false;
    h_[i].protection.reset();
  }
  // Reconfigure: the device latched its own faults.
  mu_.unlock();
  start(now_s_);
  mu_.lock();
}

void ThermalLoop::handle(const uint8_t* msg, size_t n, double now_s) {
  if (n == 0) return;
  if (msg[0] == static_cast<uint8_t>(protocol::MsgType::kHeaterReport)) {
    protocol::HeaterReportMsg r;
    if (!protocol::decode_heater_report(msg, n, r) || r.heater >= h_.size()) return;
    const int i = r.heater;
    Heater& h = h_[static_cast<size_t>(i)];
    const HeaterSpec& s = opt_.heaters[static_cast<size_t>(i)];
    const double t = static_cast<double>(r.clock) / opt_.mcu_clock_hz;
    h.adc = r.adc / 65535.0;
    h.temp_c = thermal::temp_at_adc(s.sensor, h.adc);
    h.have_temp = true;
    h.last_report_s = t;
    h.last_arrival_s = now_s;
    if (h.faulted) return;
    const thermal::ThermalFault f = h.protection.check(t, h.temp_c, h.target_c, h.adc, r.duty > 0);
    if (f) {
      char buf[200];
      trip(i, thermal::describe(f, buf, sizeof buf), now_s);
      return;
    }
    double power = 0.0;
    if (h.autotune) {
      power = h.autotune->update(t, h.temp_c);
      if (h.autotune->state() != thermal::AutotuneState::kRunning) {
        if (h.autotune->state() == thermal::AutotuneState::kDone) {
          autotune_result_ = h.autotune->result();
        } else {
          autotune_result_ =
              Error{std::string("PID autotune of ") + s.name + " failed: " +
                    (h.autotune->state() == thermal::AutotuneState::kTooHot ? "temperature too high"
                                                                            : "timeout")};
        }
        h.autotune.reset();
        h.target_c = 0.0;
        power = 0.0;
      }
    } else {
      power = h.pid.update(t, h.temp_c, h.target_c);
    }
    send_heater(i, power, now_s);  // also the re-confirmation the MCU waits for
  } else if (msg[0] == static_cast<uint8_t>(protocol::MsgType::kHeaterFault)) {
    protocol::HeaterFaultMsg m;
    if (!protocol::decode_heater_fault(msg, n, m) || m.heater >= h_.size()) return;
    const HeaterSpec& s = opt_.heaters[m.heater];
    char buf[200];
    const double adc = m.adc / 65535.0;
    thermal::ThermalFault f;
    f.t_s = static_cast<double>(m.clock) / opt_.mcu_clock_hz;
    f.temp_c = thermal::temp_at_adc(s.sensor, adc);
    if (m.reason == protocol::HeaterFaultReason::kWatchdog) {
      f.rule = thermal::ThermalRule::kMcuWatchdog;
      f.a = s.confirm_timeout_s;
    } else if (adc >= s.protection.open_adc) {
      f.rule = thermal::ThermalRule::kSensorOpen;
      f.a = adc;
    } else if (adc <= s.protection.short_adc) {
      f.rule = thermal::ThermalRule::kSensorShort;
      f.a = adc;
    } else if (f.temp_c > s.protection.max_temp_c) {
      f.rule = thermal::ThermalRule::kMcuMaxTemp;
      f.a = s.protection.max_temp_c;
    } else {
      f.rule = thermal::ThermalRule::kMinTemp;
      f.a = s.protection.min_temp_c;
    }
    std::string why = thermal::describe(f, buf, sizeof buf);
    if (m.reason == protocol::HeaterFaultReason::kBadConfig)
      why = "the MCU refused its configuration";
    else
      why += " (detected by the MCU)";
    trip(m.heater, why, now_s);
  }
}

// The reports stopped (the board lost power, its cable is out, its firmware hangs): its own 3 s
// rule turns a heater off there, if it still runs; here the machine stops and says which heater.
// The freshness is the later of the report's own time (the MCU's clock mapped to the host's) and
// its arrival, or any frame from its MCU: a board still talking (retransmitting what it sent while
// the host stalled) is not a board without power; its own fault then names the rule.
void ThermalLoop::check_reports(double now_s) {
  for (size_t i = 0; i < h_.size(); ++i) {
    const HeaterSpec& s = opt_.heaters[i];
    const double since_s = h_[i].have_temp ? std::max({h_[i].last_report_s, h_[i].last_arrival_s,
                                                       link_->last_heard_s(static_cast<int>(i))})
                                           : reports_due_from_s_;
    if (now_s - since_s <= s.report_timeout_s) continue;
    char buf[64];
    std::snprintf(buf, sizeof buf, "no temperature report for %.1f s (", now_s - since_s);
    const std::string why =
        buf +
        std::string(h_[i].have_temp ? "its MCU stopped reporting" : "its MCU never reported") +
        link_->heater_place(static_cast<int>(i)) + ")";
    trip(static_cast<int>(i), why, now_s);
    return;
  }
}

std::optional<std::string> ThermalLoop::step_to(double t_s) {
  std::lock_guard lock(mu_);
  if (t_s < now_s_) t_s = now_s_;
  // In steps of at most 50 ms, so that the answer to a report (its SET_HEATER) leaves within 50 ms
  // of the machine time whatever the caller's stride (virtual time may jump far between calls).
  while (now_s_ < t_s) {
    const double t = std::min(t_s, now_s_ + 0.05);
    now_s_ = t;
    link_->advance_to(t);
    uint8_t buf[32];
    size_t n = 0;
    while (link_->receive(buf, n)) handle(buf, n, t);
    update_heater_fans(t);
    if (!fault_) {
      if (std::optional<std::string> lost = link_->fault()) {
        // The heaters' MCU is lost or unusable: nothing is confirmed any more (its own 3 s rule
        // turns them off there); here every target is dropped and the machine stops.
        fault_ = *lost;
        for (size_t k = 0; k < h_.size(); ++k) {
          h_[k].target_c = 0.0;
          h_[k].autotune.reset();
          send_heater(static_cast<int>(k), 0.0, t);
        }
        if (autotune_heater_ >= 0 && !autotune_result_)
          autotune_result_ = Error{"autotune stopped: " + *fault_};
      }
    }
    if (!fault_) check_reports(t);
  }
  if (fault_ && !fault_reported_) {
    fault_reported_ = true;
    return fault_;
  }
  return std::nullopt;
}

Status ThermalLoop::start_autotune(int heater, double target_c, int cycles) {
  std::lock_guard lock(mu_);
  if (heater < 0 || heater >= static_cast<int>(h_.size())) return Error{"M303: no such heater"};
  const HeaterSpec& s = opt_.heaters[static_cast<size_t>(heater)];
  if (fault_)
    return Error{"M303: heaters are off after a thermal fault (" + *fault_ + "); send M999"};
  if (!(target_c > 0 && target_c < s.protection.max_temp_c - 5.0))
    return Error{"M303: S must be above 0 and at least 5 C below max_temp_c of " + s.name};
  thermal::AutotuneParams p;
  p.target_c = target_c;
  p.cycles = std::clamp(cycles, 3, 20);
  p.max_power = s.pid.max_power;
  p.max_temp_c = s.protection.max_temp_c - 1.0;
  Heater& h = h_[static_cast<size_t>(heater)];
  h.autotune.emplace(p);
  h.target_c = target_c;  // the protection watches the autotune like any heat-up
  autotune_heater_ = heater;
  autotune_result_.reset();
  return Status::Ok();
}

std::optional<Result<thermal::PidParams>> ThermalLoop::autotune_done(bool use_result) {
  std::lock_guard lock(mu_);
  if (!autotune_result_) return std::nullopt;
  auto r = std::move(autotune_result_);
  autotune_result_.reset();
  if (use_result && r->ok() && autotune_heater_ >= 0)
    h_[static_cast<size_t>(autotune_heater_)].pid.set_params(r->value());
  autotune_heater_ = -1;
  return r;
}

std::string ThermalLoop::marlin_report() const {
  std::lock_guard lock(mu_);
  std::string temps, powers;
  char buf[64];
  int tool = 0;
  for (size_t i = 0; i < h_.size(); ++i) {
    const char m = opt_.heaters[i].marlin;
    // Marlin: T (the active hotend), T1.. for more; B, C; powers as @:, @1:, B@:, C@: (0..127).
    std::string letter(1, m), power_label;
    if (m == 'T') {
      if (tool > 0) letter += std::to_string(tool);
      power_label = tool > 0 ? "@" + std::to_string(tool) : "@";
      ++tool;
    } else {
      power_label = letter + "@";
    }
    std::snprintf(buf, sizeof buf, "%s%s:%.1f /%.1f", temps.empty() ? "" : " ", letter.c_str(),
                  h_[i].temp_c, h_[i].target_c);
    temps += buf;
    std::snprintf(buf, sizeof buf, " %s:%d", power_label.c_str(),
                  static_cast<int>(std::lround(h_[i].power * 127.0)));
    powers += buf;
  }
  return temps + powers;
}

thermal::ProtectionMargins ThermalLoop::margins(int heater) const {
  std::lock_guard lock(mu_);
  return h_[static_cast<size_t>(heater)].protection.margins();
}

double ThermalLoop::now_s() const {
  std::lock_guard lock(mu_);
  return now_s_;
}

void ThermalLoop::snapshot(HeaterStatus* heaters, int& nh, FanStatus* fans, int& nf) const {
  std::lock_guard lock(mu_);
  nh = static_cast<int>(h_.size());
  for (size_t i = 0; i < h_.size(); ++i) {
    HeaterStatus& s = heaters[i];
    std::snprintf(s.name, sizeof s.name, "%s", opt_.heaters[i].name.c_str());
    s.marlin = opt_.heaters[i].marlin;
    s.temp_c = h_[i].temp_c;
    s.target_c = h_[i].target_c;
    s.power = h_[i].power;
    s.faulted = h_[i].faulted;
    s.autotuning = h_[i].autotune.has_value();
  }
  nf = static_cast<int>(f_.size());
  for (size_t i = 0; i < f_.size(); ++i) {
    std::snprintf(fans[i].name, sizeof fans[i].name, "%s", opt_.fans[i].name.c_str());
    fans[i].speed = f_[i].speed;
    fans[i].part = opt_.fans[i].kind == FanSpec::Kind::kPart;
    fans[i].requested = fans[i].part ? f_[i].requested : f_[i].speed;
  }
}

}  // namespace feedloop::engine
