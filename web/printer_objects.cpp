#include "web/printer_objects.hpp"

#include <sys/sysinfo.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace feedloop::web {

using nlohmann::json;

const char* to_string(JobState s) {
  switch (s) {
    case JobState::standby:
      return "standby";
    case JobState::printing:
      return "printing";
    case JobState::paused:
      return "paused";
    case JobState::complete:
      return "complete";
    case JobState::cancelled:
      return "cancelled";
    case JobState::error:
      return "error";
  }
  return "standby";
}

std::string webhooks_state(const engine::MachineStatus& s) {
  return s.state == engine::MachineState::kEmergencyStopped ||
                 s.state == engine::MachineState::kError
             ? "shutdown"
             : "ready";
}

const json& gcode_commands() {
  static const json c = {
      {"G0", {{"help", "Linear move"}}},
      {"G1", {{"help", "Linear move"}}},
      {"G2", {{"help", "Clockwise arc"}}},
      {"G3", {{"help", "Counter-clockwise arc"}}},
      {"G4", {{"help", "Dwell"}}},
      {"G28", {{"help", "Home axes"}}},
      {"G90", {{"help", "Absolute positioning"}}},
      {"G91", {{"help", "Relative positioning"}}},
      {"G92", {{"help", "Set position"}}},
      {"M82", {{"help", "Absolute extrusion"}}},
      {"M83", {{"help", "Relative extrusion"}}},
      {"M104", {{"help", "Set hotend temperature"}}},
      {"M109", {{"help", "Set hotend temperature and wait"}}},
      {"M140", {{"help", "Set bed temperature"}}},
      {"M190", {{"help", "Set bed temperature and wait"}}},
      {"M105", {{"help", "Report temperatures"}}},
      {"M114", {{"help", "Report position"}}},
      {"M115", {{"help", "Firmware info"}}},
      {"M117", {{"help", "Display message"}}},
      {"M220", {{"help", "Speed factor"}}},
      {"M221", {{"help", "Extrusion factor"}}},
      {"M400", {{"help", "Wait for moves"}}},
      {"M112", {{"help", "Emergency stop"}}},
      {"PAUSE", {{"help", "Pause the print"}}},
      {"RESUME", {{"help", "Resume the print"}}},
      {"CANCEL_PRINT", {{"help", "Cancel the print"}}},
      {"SDCARD_PRINT_FILE", {{"help", "Print a file from the gcodes folder (FILENAME=)"}}},
      {"SDCARD_RESET_FILE", {{"help", "Clear the finished print (print_stats back to standby)"}}},
      {"EXCLUDE_OBJECT", {{"help", "Skip an object of the print (NAME=, CURRENT=1, RESET=1)"}}},
      {"EXCLUDE_OBJECT_DEFINE", {{"help", "Label an object of the print (the slicer's)"}}},
      {"EXCLUDE_OBJECT_START", {{"help", "The object's moves start (the slicer's)"}}},
      {"EXCLUDE_OBJECT_END", {{"help", "The object's moves end (the slicer's)"}}},
      {"RESTART", {{"help", "Rebuild the machine (clears an emergency stop)"}}},
      {"FIRMWARE_RESTART", {{"help", "Same as RESTART"}}},
  };
  return c;
}

HeaterPowers heater_powers(const engine::MachineStatus& s) {
  HeaterPowers p;
  bool have_t = false, have_b = false;
  for (int i = 0; i < s.num_heaters && i < engine::ThermalLoop::kMaxHeaters; ++i) {
    const engine::HeaterStatus& h = s.heaters[i];
    if (h.marlin == 'T' && !have_t) {
      have_t = true;
      p.hotend = h.power;
    } else if (h.marlin == 'B' && !have_b) {
      have_b = true;
      p.bed = h.power;
    }
  }
  return p;
}

namespace {
json vec4(const double v[4]) {
  return json::array({v[0], v[1], v[2], v[3]});
}

json histogram(const LatencyHistogram& h) {
  json edges = json::array(), counts = json::array();
  int last = 0;
  for (int i = 0; i < LatencyHistogram::kBins; ++i)
    if (h.counts[static_cast<size_t>(i)] != 0) last = i;
  for (int i = 0; i <= last; ++i) {
    edges.push_back(static_cast<double>(LatencyHistogram::edge_ns(i)) / 1000.0);
    counts.push_back(h.counts[static_cast<size_t>(i)]);
  }
  return {{"edges_us", edges}, {"counts", counts}};
}

json links(const engine::LinkTelemetrySet& set) {
  json out = json::object();
  for (int i = 0; i < set.count && i < engine::LinkTelemetrySet::kMaxLinks; ++i) {
    const engine::LinkTelemetry& l = set.links[i];
    out[l.name] = {
        {"state", l.state},
        {"frames_sent", l.frames_sent},
        {"retransmitted", l.retransmitted},
        {"delivered", l.delivered},
        {"crc_errors", l.crc_errors},
        {"resets", l.resets},
        {"rtt_us", {{"last", l.rtt_last_us}, {"min", l.rtt_min_us}, {"mean", l.rtt_mean_us}}},
        {"clock_rate_ppm", l.clock_rate_ppm}};
  }
  return out;
}
}  // namespace

json printer_objects(const ObjectInputs& in) {
  const engine::MachineStatus& s = in.machine;
  const PrinterInfo& pi = in.info;
  const JobStatus& job = in.job;
  const bool printing = job.state == JobState::printing;
  const bool paused = job.state == JobState::paused;
  const bool busy = s.state == engine::MachineState::kBusy || s.moving || s.queue_depth > 0;
  const double amin[4] = {pi.axis_min_mm[0], pi.axis_min_mm[1], pi.axis_min_mm[2], 0.0};
  const double amax[4] = {pi.axis_max_mm[0], pi.axis_max_mm[1], pi.axis_max_mm[2], 0.0};
  const std::string state = webhooks_state(s);
  const double progress =
      job.file_size ? static_cast<double>(job.file_position) / static_cast<double>(job.file_size)
                    : 0.0;
  struct sysinfo si {};
  sysinfo(&si);
  double load[1] = {0.0};
  getloadavg(load, 1);
  timespec cpu{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &cpu);

  json o;
  o["webhooks"] = {
      {"state", state},
      {"state_message", state == "ready"
                            ? std::string("Printer is ready")
                            : std::string(s.last_error[0] ? s.last_error : "Emergency stop")}};
  const json printer_cfg = {{"kinematics", pi.kinematics},
                            {"max_velocity", pi.max_velocity_mm_s},
                            {"max_accel", pi.max_accel_mm_s2},
                            {"square_corner_velocity", pi.square_corner_velocity_mm_s}};
  // configfile: what Mainsail reads (printer limits, heaters, and the sections whose absence it
  // warns about: virtual_sdcard, pause_resume, the pause/resume/cancel macros, which feedloop
  // implements itself: PAUSE, RESUME and CANCEL_PRINT are handled by the web API).
  json settings = {{"printer", printer_cfg},
                   {"extruder",
                    {{"min_temp", 0},
                     {"max_temp", 300},
                     {"min_extrude_temp", pi.min_extrude_temp_c},
                     {"nozzle_diameter", pi.nozzle_diameter_mm},
                     {"filament_diameter", pi.filament_diameter_mm}}},
                   {"heater_bed", {{"min_temp", 0}, {"max_temp", 130}}},
                   {"virtual_sdcard", {{"path", in.gcodes_dir}}},
                   {"pause_resume", json::object()},
                   {"display_status", json::object()},
                   {"gcode_macro pause", {{"gcode", "PAUSE"}}},
                   {"gcode_macro resume", {{"gcode", "RESUME"}}},
                   {"gcode_macro cancel_print", {{"gcode", "CANCEL_PRINT"}}}};
  json config = json::object();
  for (auto& [k, v] : settings.items()) {
    json section = json::object();
    for (auto& [kk, vv] : v.items())
      section[kk] = vv.is_string() ? vv.get<std::string>() : vv.dump();
    config[k == "gcode_macro pause"          ? "gcode_macro PAUSE"
           : k == "gcode_macro resume"       ? "gcode_macro RESUME"
           : k == "gcode_macro cancel_print" ? "gcode_macro CANCEL_PRINT"
                                             : k] = section;
  }
  o["configfile"] = {{"config", config},
                     {"settings", settings},
                     {"save_config_pending", false},
                     {"save_config_pending_items", json::object()},
                     {"warnings", json::array()}};
  o["toolhead"] = {{"homed_axes", std::string(s.homed_axes)},
                   {"position", vec4(s.pos_mm)},
                   {"axis_minimum", vec4(amin)},
                   {"axis_maximum", vec4(amax)},
                   {"max_velocity", pi.max_velocity_mm_s},
                   {"max_accel", pi.max_accel_mm_s2},
                   {"square_corner_velocity", pi.square_corner_velocity_mm_s},
                   {"minimum_cruise_ratio", pi.min_cruise_ratio},
                   {"extruder", "extruder"},
                   {"print_time", s.planned_until_s},
                   {"estimated_print_time", s.print_time_s},
                   {"stalls", s.late_cycles}};
  o["gcode_move"] = {{"speed_factor", s.speed_factor},   // M220 (Mainsail's speed slider)
                     {"extrude_factor", s.flow_factor},  // M221 (its flow slider)
                     {"absolute_coordinates", s.absolute_coordinates},
                     {"absolute_extrude", s.absolute_extrude},
                     {"homing_origin", json::array({0.0, 0.0, 0.0, 0.0})},
                     {"position", vec4(s.pos_mm)},
                     {"gcode_position", vec4(s.pos_mm)},
                     // Klipper's gcode_move.speed is the G-code's F (mm/min); Mainsail shows
                     // speed / 60 x speed_factor as the requested speed.
                     {"speed", s.feedrate_mm_s * 60.0}};
  o["print_stats"] = {{"filename", job.filename},
                      {"total_duration", job.total_duration_s},
                      {"print_duration", job.print_duration_s},
                      {"filament_used", job.filament_used_mm},
                      {"state", to_string(job.state)},
                      {"message", job.message},
                      {"info", {{"total_layer", nullptr}, {"current_layer", nullptr}}}};
  o["virtual_sdcard"] = {
      {"file_path",
       job.filename.empty() ? json(nullptr) : json(in.gcodes_dir + "/" + job.filename)},
      {"progress", progress},
      {"is_active", printing},
      {"file_position", job.file_position},
      {"file_size", job.file_size}};
  o["pause_resume"] = {{"is_paused", paused}};
  // Klipper's exclude_object (klippy/extras/exclude_object.py): Mainsail and Fluidd list the
  // objects and send EXCLUDE_OBJECT NAME=... (no CENTER or POLYGON kept: the UIs draw no map).
  json labelled = json::array();
  for (const std::string& name : in.objects.defined()) labelled.push_back({{"name", name}});
  o["exclude_object"] = {
      {"objects", labelled},
      {"excluded_objects", in.objects.excluded()},
      {"current_object",
       in.objects.current().empty() ? json(nullptr) : json(in.objects.current())}};
  o["display_status"] = {{"progress", progress}, {"message", nullptr}};
  o["idle_timeout"] = {{"state", printing || busy ? "Printing" : "Ready"},
                       {"printing_time", job.print_duration_s}};
  o["heaters"] = {{"available_heaters", {"extruder", "heater_bed"}},
                  {"available_sensors", {"extruder", "heater_bed"}},
                  {"available_monitors", json::array()}};
  // Heater power and fans from the thermal loop (engine/thermal_loop.hpp): the first hotend is
  // Klipper's `extruder`, the first bed `heater_bed`; the first part fan (M106/M107) is `fan`,
  // each heater fan `heater_fan <name>` (Klipper's [fan] and [heater_fan] objects).
  const HeaterPowers powers = heater_powers(s);
  o["extruder"] = {{"temperature", s.hotend_c},
                   {"target", s.hotend_target_c},
                   {"power", powers.hotend},
                   {"can_extrude", s.hotend_c >= 170.0},
                   {"pressure_advance", s.pressure_advance_s},
                   {"smooth_time", s.pressure_advance_smooth_time_s}};
  o["heater_bed"] = {{"temperature", s.bed_c}, {"target", s.bed_target_c}, {"power", powers.bed}};
  bool have_part = false;
  o["fan"] = {{"speed", 0.0}, {"rpm", nullptr}};
  for (int i = 0; i < s.num_fans && i < engine::ThermalLoop::kMaxFans; ++i) {
    const engine::FanStatus& f = s.fans[i];
    if (f.part && !have_part) {
      have_part = true;
      o["fan"]["speed"] = f.requested;  // Klipper's fan.py reports the requested speed
    } else if (!f.part) {
      o[std::string("heater_fan ") + f.name] = {{"speed", f.requested}, {"rpm", nullptr}};
    }
  }
  o["motion_report"] = {
      {"live_position", vec4(s.pos_mm)},
      {"live_velocity", 0.0},
      {"live_extruder_velocity", 0.0},
      {"steppers", json::array({"stepper_x", "stepper_y", "stepper_z", "extruder"})},
      {"trapq", json::array({"toolhead", "extruder"})}};
  o["system_stats"] = {
      {"sysload", load[0]},
      {"cputime", static_cast<double>(cpu.tv_sec) + static_cast<double>(cpu.tv_nsec) * 1e-9},
      {"memavail", static_cast<double>(si.freeram) * si.mem_unit / 1024.0}};
  o["gcode"] = {{"commands", gcode_commands()}};
  // feedloop's own.
  o["feedloop_servo"] = {
      {"period_s", pi.servo_period_s},
      {"cycles", in.servo.cycles},
      {"deadline_misses", in.servo.deadline_misses},
      {"latency_us",
       {{"p50", static_cast<double>(in.servo.latency.percentile_ns(0.50)) / 1000.0},
        {"p99", static_cast<double>(in.servo.latency.percentile_ns(0.99)) / 1000.0},
        {"max", static_cast<double>(in.servo.latency.max_ns) / 1000.0}}},
      {"latency_histogram", histogram(in.servo.latency)}};
  o["feedloop_links"] = {{"links", links(s.links)}};
  o["feedloop_tracking"] = in.tracking.summary(s);
  return o;
}

}  // namespace feedloop::web
