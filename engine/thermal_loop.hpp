// The host side of heaters and fans (docs/heaters.md): per heater the PID (thermal/pid.hpp) or
// the M303 relay autotune, the thermal protection (thermal/protection.hpp) on every report, and the
// re-confirmation the MCU needs (every SET_HEATER is one; reports come every 0.3 s, the MCU's
// limit is 3 s: Klipper's REPORT_TIME and MAX_HEAT_TIME); part fans (M106/M107, kick-start) and
// heater fans (on above a temperature). It talks to the MCU side through a HeaterLink with the
// protocol v3 messages (drivers/protocol/heater_messages.hpp).
// Not real-time: stepped by the machine's thermal thread and, while an M109/M190/M303 waits in
// virtual time, by the planner thread; a mutex guards it. Times are the machine clock's, seconds.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "thermal/autotune.hpp"
#include "thermal/pid.hpp"
#include "thermal/protection.hpp"
#include "thermal/sensor.hpp"

namespace feedloop::engine {

// The MCU side as the host sees it: protocol v3 payloads each way.
class HeaterLink {
 public:
  virtual ~HeaterLink() = default;
  virtual void send(double now_s, const uint8_t* msg, size_t n) = 0;
  // Lets the device side (and a simulated plant) run up to t_s.
  virtual void advance_to(double t_s) = 0;
  // Next message from the device; false when none. out holds at least 32 bytes.
  virtual bool receive(uint8_t* out, size_t& n) = 0;
  // Set when the link to the heaters is lost or unusable (which MCU, why): a thermal fault.
  virtual std::optional<std::string> fault() const { return std::nullopt; }
  // Where heater i lives, for messages ("MCU 'board'"); "" when the link has one place only.
  virtual std::string heater_place(int /*heater*/) const { return {}; }
  // Host time anything last arrived from heater i's MCU (frames of any kind); -inf: unknown.
  virtual double last_heard_s(int /*heater*/) const { return -1e300; }
};

struct HeaterSpec {
  std::string name = "extruder";
  char marlin =
      'T';       // how Marlin names it: 'T' hotend (M104/M109), 'B' bed (M140/M190), 'C' chamber
  int tool = 0;  // T index among the hotends
  thermal::SensorParams sensor;
  thermal::PidParams pid;
  thermal::ProtectionParams protection;
  double report_period_s = 0.3;    // Klipper's REPORT_TIME
  int oversample = 8;              // ADC samples per report
  double confirm_timeout_s = 3.0;  // the MCU's own off switch (Klipper's MAX_HEAT_TIME)
  // The host's side of it: no report for this long (a board without power, a cable out) is a
  // thermal fault. The first report is due report_grace_s after start() plus this.
  double report_timeout_s = 2.0;
  double report_grace_s = 3.0;  // an MCU's identification and configuration
  // M109/M190 waits (Marlin TEMP_WINDOW, TEMP_HYSTERESIS, TEMP_RESIDENCY_TIME).
  double window_c = 1.0, hysteresis_c = 3.0, residency_s = 10.0;
};

struct FanSpec {
  std::string name = "part";
  enum class Kind : uint8_t { kPart, kHeater } kind = Kind::kPart;
  int heater = -1;              // heater fans: the heater they cool
  double heater_temp_c = 50.0;  // heater fans: on above (Klipper heater_fan's heater_temp)
  double kick_start_s = 0.1;    // full power this long when starting (Klipper kick_start_time)
  double off_below = 0.0;       // speeds below this are off (Klipper off_below)
  double max_power = 1.0;
};

struct ThermalOptions {
  std::vector<HeaterSpec> heaters;
  std::vector<FanSpec> fans;
  double mcu_clock_hz = 1e6;  // ticks of the heater MCU's clock per second
};

// Status of one heater / fan (trivially copyable, for the machine's status seqlock).
struct HeaterStatus {
  char name[16] = {};
  char marlin = 'T';
  double temp_c = 0.0, target_c = 0.0, power = 0.0;
  bool faulted = false;
  bool autotuning = false;
};
struct FanStatus {
  char name[16] = {};
  double speed = 0.0;      // the output now (full power during a kick-start)
  double requested = 0.0;  // what M106 asked (Klipper's fan status `speed`); heater fans: speed
  bool part = true;        // a part fan (M106/M107); false: a heater fan
};

class ThermalLoop {
 public:
  static constexpr int kMaxHeaters = 4;
  static constexpr int kMaxFans = 4;

  ThermalLoop(ThermalOptions options, std::unique_ptr<HeaterLink> link);
  // Configures every heater on the device (CONFIGURE_HEATER); heaters off.
  void start(double now_s);
  // Runs the device side to t_s and handles its reports. Returns the fault message (once).
  std::optional<std::string> step_to(double t_s);

  int num_heaters() const { return static_cast<int>(opt_.heaters.size()); }
  int num_fans() const { return static_cast<int>(opt_.fans.size()); }
  // The heater Marlin calls `marlin` (T/B/C) with that tool index; -1 when there is none.
  int find_heater(char marlin, int tool = 0) const;
  const HeaterSpec& spec(int heater) const { return opt_.heaters[static_cast<size_t>(heater)]; }
  // A target above max_temp is refused (Marlin clamps, Klipper refuses: we refuse with a message).
  Status set_target(int heater, double target_c);
  double target_c(int heater) const;
  double temp_c(int heater) const;
  // Marlin's M109 test, fed by the caller while it waits: true once the temperature stayed within
  // window_c of the target for residency_s (heating_only: any temperature above the target counts).
  bool reached(int heater, bool heating_only, double now_s);
  // Part fans (M106/M107): index among the part fans; speed 0..1.
  Status set_fan(int part_fan, double speed, double now_s);
  // M303: relay autotune of a heater at target_c for `cycles` cycles; poll autotune_done().
  Status start_autotune(int heater, double target_c, int cycles);
  // nullopt while running; the result (or an error) once done. use_result: set the gains.
  std::optional<Result<thermal::PidParams>> autotune_done(bool use_result);
  // Every heater off (fault, emergency stop, shutdown).
  void all_off(double now_s);
  std::optional<std::string> fault() const;
  void clear_fault();  // M999
  // Marlin's temperature report: "T:210.0 /210.0 B:60.0 /60.0 @:127 B@:64".
  std::string marlin_report() const;
  void snapshot(HeaterStatus* heaters, int& nh, FanStatus* fans, int& nf) const;
  thermal::ProtectionMargins margins(int heater) const;
  HeaterLink& link() { return *link_; }
  double now_s() const;

 private:
  struct Heater {
    thermal::HeaterPid pid;
    thermal::ThermalProtection protection;
    std::optional<thermal::RelayAutotune> autotune;
    double target_c = 0.0, temp_c = 0.0, power = 0.0, adc = 0.0, last_report_s = 0.0;
    double last_arrival_s = 0.0;  // host time the last report was handled
    bool have_temp = false, faulted = false;
    double in_window_since_s = -1.0;
  };
  struct Fan {
    double speed = 0.0, requested = 0.0, kick_until_s = -1.0;
  };
  void handle(const uint8_t* msg, size_t n, double now_s);
  void send_heater(int i, double power, double now_s);
  void send_fan(int i, double speed, double now_s);
  void trip(int i, const std::string& why, double now_s);
  void update_heater_fans(double now_s);
  void check_reports(double now_s);
  int64_t clock_of(double t_s) const { return static_cast<int64_t>(t_s * opt_.mcu_clock_hz); }

  ThermalOptions opt_;
  std::unique_ptr<HeaterLink> link_;
  mutable std::mutex mu_;
  std::vector<Heater> h_;
  std::vector<Fan> f_;
  double now_s_ = 0.0;
  double reports_due_from_s_ = 0.0;  // start() + the grace: until a heater's first report
  std::optional<std::string> fault_;
  bool fault_reported_ = false;
  int autotune_heater_ = -1;
  std::optional<Result<thermal::PidParams>> autotune_result_;
};

}  // namespace feedloop::engine
