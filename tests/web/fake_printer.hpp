// A printer for the web API's tests, fuzz target and load test: no machine. G-code lines are
// answered at once (M105 with the temperatures; a line starting with "BAD" fails), M104 sets the
// hotend target, jobs move through their states, and moves set the position (G1 X.. Y.. Z..).
#pragma once

#include <cstdlib>
#include <string>

#include "web/printer_backend.hpp"

namespace feedloop::web::testing {

class FakePrinter final : public PrinterBackend {
 public:
  PrinterInfo printer_info() const override {
    PrinterInfo p;
    p.name = "fake";
    p.kinematics = "cartesian";
    p.version = "test";
    p.axis_max_mm[0] = p.axis_max_mm[1] = 200;
    p.axis_max_mm[2] = 180;
    p.max_velocity_mm_s = 300;
    p.max_accel_mm_s2 = 3000;
    return p;
  }
  engine::MachineStatus machine_status() const override { return status; }
  engine::ServoStatus servo_status() const override { return servo; }
  JobStatus job_status() const override { return job; }
  void run_gcode(std::string script, std::function<void(bool, std::string)> done) override {
    ++scripts;
    last_script = script;
    if (script.rfind("BAD", 0) == 0) return done(false, "unknown command " + script);
    std::string reply;
    size_t b = 0;
    while (b <= script.size()) {
      size_t e = script.find('\n', b);
      if (e == std::string::npos) e = script.size();
      const std::string line = script.substr(b, e - b);
      if (line.rfind("M105", 0) == 0)
        reply += "ok T:" + std::to_string(status.hotend_c) + " /0.0 B:21.0 /0.0\n";
      if (line.rfind("M104 S", 0) == 0) status.hotend_target_c = std::atof(line.c_str() + 6);
      if (line.rfind("G1", 0) == 0)
        for (int a = 0; a < 3; ++a)
          if (size_t at = line.find("XYZ"[a]); at != std::string::npos)
            status.pos_mm[a] = std::atof(line.c_str() + at + 1);
      b = e + 1;
    }
    if (!reply.empty()) reply.pop_back();
    done(true, reply);
  }
  std::string start_job(const std::string& path, const std::string& filename) override {
    if (job.state == JobState::printing || job.state == JobState::paused)
      return "a print is already running";
    job = JobStatus{};
    job.state = JobState::printing;
    job.filename = filename;
    job.file_size = 1000;
    last_job_path = path;
    return {};
  }
  std::string pause_job() override {
    if (job.state != JobState::printing) return "Print is not in progress";
    job.state = JobState::paused;
    return {};
  }
  std::string resume_job() override {
    if (job.state != JobState::paused) return "Print is not paused, resume aborted";
    job.state = JobState::printing;
    return {};
  }
  std::string cancel_job() override {
    if (job.state != JobState::printing && job.state != JobState::paused)
      return "No print in progress";
    job.state = JobState::cancelled;
    return {};
  }
  void emergency_stop(const std::string&) override {
    status.state = engine::MachineState::kEmergencyStopped;
  }
  void restart() override { status.state = engine::MachineState::kIdle; }

  engine::MachineStatus status{};
  engine::ServoStatus servo{};
  JobStatus job;
  int scripts = 0;
  std::string last_script, last_job_path;
};

}  // namespace feedloop::web::testing
