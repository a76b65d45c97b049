// A thermal loop on the simulated printer's heater MCU and plants, stepped in virtual time.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "config/config.hpp"
#include "engine/simulated_printer.hpp"
#include "engine/thermal_config.hpp"
#include "sim/thermal_plant.hpp"

namespace feedloop::engine::testing {

struct ThermalRig {
  explicit ThermalRig(config::MachineConfig c = config::default_config(), uint64_t seed = 1)
      : cfg(std::move(c)) {
    cfg.simulator.seed = seed;
    loop = std::move(make_thermal_loop(cfg).value());
    loop->start(0.0);
  }
  sim::ThermalPlant& plant(int i) { return *simulated_thermal_plant(loop->link(), i); }
  // Runs to t_end in 50 ms strides; returns the fault message, if any (t_fault set).
  std::optional<std::string> run_until(double t_end,
                                       const std::function<bool(double)>& stop = nullptr) {
    for (; t < t_end;) {
      t += 0.05;
      auto f = loop->step_to(t);
      const bool done = stop && stop(t);  // sees the plant at every step, the fault's too
      if (f) {
        t_fault = t;
        return f;
      }
      if (done) return std::nullopt;
    }
    return std::nullopt;
  }
  config::MachineConfig cfg;
  std::unique_ptr<ThermalLoop> loop;
  double t = 0.0, t_fault = -1.0;
};

}  // namespace feedloop::engine::testing
