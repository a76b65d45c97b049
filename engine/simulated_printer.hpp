// The simulated transport's factory: from the printer config to the plants behind the mock
// transport's virtual MCUs (sim::GantryAxis per Cartesian axis with the configured steps/mm,
// encoder and simulator effects; one sim::DeltaPlant for a delta's carriages). The only place in
// engine/ that includes the plant simulator (sim/, in simulated_printer.cpp; this header only
// names its types); everything else in engine/ uses the SimulatedPlant interface.
#pragma once

#include <memory>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/simulated_plant.hpp"
#include "engine/mcu_heater_link.hpp"
#include "engine/thermal_loop.hpp"

namespace feedloop::sim {
class DeltaPlant;
class GantryAxis;
struct GantryAxisParams;
class ThermalPlant;
class PartFan;
}  // namespace feedloop::sim

namespace feedloop::engine {

// The plants of the config's machine. Errors: a plant the simulator cannot build (bad steps/mm,
// an unreachable delta start), named after the axis.
Result<std::unique_ptr<SimulatedPlant>> make_simulated_printer(const config::MachineConfig& cfg);

// The simulated plant of gantry joint `joint` (0 x, 1 y, 2 z) of a Cartesian / CoreXY config: the
// thesis's axis with the configured steps/mm, encoder and simulator effects. What the factory
// builds; also what an identification run on the simulated machine excites (bench_control).
// Errors: steps_per_mm not > 0. (Include sim/gantry_params.hpp to use the result.)
Result<sim::GantryAxisParams> simulated_gantry_params(const config::MachineConfig& cfg, int joint);

// The concrete plants behind a plant built by make_simulated_printer, for tests and benchmarks
// (include sim/gantry_axis.hpp, sim/delta_plant.hpp to use them). nullptr: no such plant.
sim::GantryAxis* simulated_gantry(SimulatedPlant& plant, int joint);
sim::DeltaPlant* simulated_delta(SimulatedPlant& plant);

// The simulated printer's heaters and fans: a heater MCU (drivers/device/virtual_mcu.hpp hosting a
// heater_board.hpp, at stepgen.mcu_clock_hz) behind a mock transport, reached through its
// McuSession (protocol v3 in frames); its board drives a thermal plant per configured heater
// (sim/thermal_plant.hpp, with the heater's plant: parameters) and the part fans cooling the
// extruders' plants. host_clock_hz: the thermal loop's ticks per second.
std::unique_ptr<McuHeaterLink> make_simulated_heater_link(const config::MachineConfig& cfg,
                                                          double host_clock_hz);
// One simulated heater board named `name` (its VirtualMcu at clock_hz) driving the config's heaters
// and fans of those indices (its channels 0, 1, .. in that order): in-process behind a mock
// transport (simulated_heater_mcu, a heater_mcus entry with transport mock), or on a pty
// (feedloop-vmcu --heater-board).
std::unique_ptr<SimulatedHeaterDevice> make_simulated_heater_device(
    const config::MachineConfig& cfg, const std::vector<int>& heaters, const std::vector<int>& fans,
    double clock_hz, const std::string& name);
// The device side of a simulated heater board without its MCU: the HeaterBoard and the thermal
// plants and fans it drives (channels 0, 1, ..: the config's heaters and fans of those indices;
// its ports take clock / clock_hz as time). A motion MCU's VirtualMcu hosts it when heaters name
// that MCU (McuBridge; one board for motion and heaters).
class SimulatedHeaterBoard {
 public:
  virtual ~SimulatedHeaterBoard() = default;
  virtual device::HeaterBoard& board() = 0;
  virtual sim::ThermalPlant* plant(int channel) = 0;  // nullptr: none
  virtual sim::PartFan* fan(int channel) = 0;
};
std::unique_ptr<SimulatedHeaterBoard> make_simulated_heater_board(const config::MachineConfig& cfg,
                                                                  const std::vector<int>& heaters,
                                                                  const std::vector<int>& fans,
                                                                  double clock_hz);
HeaterMcu simulated_heater_mcu(const config::MachineConfig& cfg, const std::vector<int>& heaters,
                               const std::vector<int>& fans, double clock_hz,
                               const std::string& name, uint64_t fault_seed);
// Its plants and part fans, for tests and benchmarks (include sim/thermal_plant.hpp); nullptr: none.
sim::ThermalPlant* simulated_thermal_plant(HeaterLink& link, int heater);
sim::PartFan* simulated_part_fan(HeaterLink& link, int fan);

}  // namespace feedloop::engine
