// Section-level comparison of two configs (see diff.hpp).
#include "config/diff.hpp"

namespace feedloop::config {

std::vector<std::string> changed_sections(const MachineConfig& a, const MachineConfig& b) {
  std::vector<std::string> out;
  const auto check = [&out](bool same, const char* name) {
    if (!same) out.emplace_back(name);
  };
  check(a.name == b.name, "name");
  check(a.kinematics == b.kinematics, "kinematics");
  check(a.drive == b.drive, "drive");
  check(a.axes == b.axes, "axes");
  check(a.delta == b.delta, "delta");
  check(a.planner == b.planner, "planner");
  check(a.extruder == b.extruder, "extruder");
  check(a.servo == b.servo, "servo");
  check(a.control == b.control, "control");
  check(a.feedforward == b.feedforward, "feedforward");
  check(a.model == b.model, "model");
  check(a.stepgen == b.stepgen, "stepgen");
  check(a.mcus == b.mcus, "mcus");
  check(a.heater_mcus == b.heater_mcus, "heater_mcus");
  check(a.heaters == b.heaters, "heaters");
  check(a.fans == b.fans, "fans");
  check(a.simulator == b.simulator, "simulator");
  check(a.sockets == b.sockets, "sockets");
  check(a.web == b.web, "web");
  check(a.recorder == b.recorder, "recorder");
  check(a.jobs == b.jobs, "jobs");
  check(a.logging == b.logging, "logging");
  return out;
}

}  // namespace feedloop::config
