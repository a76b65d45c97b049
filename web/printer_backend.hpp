// What the web API (Moonraker's, for Mainsail and Fluidd) needs from the printer: one small
// interface the daemon implements (daemon/daemon.cpp, "web backend"). Everything is called on
// the daemon's I/O thread; callbacks come back on it.
#pragma once

#include <functional>
#include <string>

#include "engine/machine.hpp"

namespace feedloop::web {

// Klipper's print_stats states (klippy/extras/print_stats.py).
enum class JobState { standby, printing, paused, complete, cancelled, error };
const char* to_string(JobState s);

struct JobStatus {
  JobState state = JobState::standby;
  std::string filename;  // relative to the gcodes root
  uint64_t file_position = 0;
  uint64_t file_size = 0;
  double print_duration_s = 0.0;  // time spent printing (not paused)
  double total_duration_s = 0.0;  // since the start
  double filament_used_mm = 0.0;
  std::string message;  // why it ended in error
};

struct PrinterInfo {
  std::string name;
  std::string kinematics;  // cartesian, corexy, delta
  std::string version;
  double axis_min_mm[3] = {0, 0, 0};
  double axis_max_mm[3] = {0, 0, 0};
  double max_velocity_mm_s = 0.0;
  double max_accel_mm_s2 = 0.0;
  double square_corner_velocity_mm_s = 5.0;
  double min_cruise_ratio = 0.5;
  double servo_period_s = 0.001;
  bool simulated = false;
  // The extruder section (Klipper's configfile.settings.extruder), from the config.
  double min_extrude_temp_c = 170.0;
  double nozzle_diameter_mm = 0.4;
  double filament_diameter_mm = 1.75;
};

class PrinterBackend {
 public:
  virtual ~PrinterBackend() = default;
  virtual PrinterInfo printer_info() const = 0;
  virtual engine::MachineStatus machine_status() const = 0;
  virtual engine::ServoStatus servo_status() const = 0;
  virtual JobStatus job_status() const = 0;
  // The G-code's object labels (Klipper's exclude_object object). Default: none.
  virtual planner::ObjectLabels object_labels() const { return {}; }
  // Runs G-code lines one after the other; `done(ok, response)` once all have run (or the first
  // failed): response holds the lines the printer answered (M105, M114...) or the error.
  virtual void run_gcode(std::string script,
                         std::function<void(bool ok, std::string response)> done) = 0;
  // Print jobs. Each returns an error text ("" on success).
  virtual std::string start_job(const std::string& path, const std::string& filename) = 0;
  // Why a file of this name (relative to the gcodes root) could not be printed, "" when it could:
  // an upload is refused then, rather than kept as a file that job.start refuses.
  virtual std::string job_name_error(const std::string& /*filename*/) const { return {}; }
  virtual std::string pause_job() = 0;
  virtual std::string resume_job() = 0;
  virtual std::string cancel_job() = 0;
  // Klipper's SDCARD_RESET_FILE: forget the finished job (print_stats back to standby).
  virtual std::string reset_job() { return {}; }
  virtual void emergency_stop(const std::string& reason) = 0;
  // Klipper's RESTART: rebuilds the machine (clears an emergency stop) once it is idle.
  virtual void restart() = 0;
};

}  // namespace feedloop::web
