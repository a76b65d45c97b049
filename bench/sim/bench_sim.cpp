// Plant simulator speed: simulated seconds per wall-clock second for a Cartesian machine (three
// thesis gantry axes) and the delta (three carriages + rigid two-mass effector), each driven by
// ideal step pulses along a 100 mm/s circle with encoder reads at 1 kHz, at two RK4 substep rates.
// Usage: bench_sim [--json FILE] [--seconds S]
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "model/delta_kinematics.hpp"
#include "sim/delta_plant.hpp"
#include "sim/gantry_axis.hpp"
#include "sim/step_driver.hpp"

namespace {

using feedloop::sim::DeltaPlant;
using feedloop::sim::DeltaPlantParams;
using feedloop::sim::GantryAxis;
using feedloop::sim::GantryAxisParams;
using feedloop::sim::StepDriver;
using Clock = std::chrono::steady_clock;

constexpr double kPi = 3.14159265358979323846;
constexpr double kStepUpdate_s = 50e-6;  // step generator update (steps spread inside)
constexpr double kRadius_mm = 20.0, kSpeed_mm_s = 100.0;

struct Row {
  std::string machine;
  double substep_hz;
  double sim_s;
  double wall_s;
  long long steps;
};

Row run_cartesian(double substep_hz, double sim_s) {
  std::array<GantryAxisParams, 3> ps{feedloop::sim::thesis_x_axis(), feedloop::sim::thesis_y_axis(),
                                     feedloop::sim::thesis_x_axis()};
  std::vector<GantryAxis> axes;
  for (auto& p : ps) {
    p.substep_hz = substep_hz;
    axes.push_back(std::move(GantryAxis::create(p).value()));
  }
  std::vector<StepDriver> drivers;
  for (auto& a : axes) drivers.emplace_back(a, a.mm_per_step());
  const double w = kSpeed_mm_s / kRadius_mm;
  long long reads = 0, steps = 0;
  const auto t0 = Clock::now();
  const int n = static_cast<int>(sim_s / kStepUpdate_s);
  for (int k = 1; k <= n; ++k) {
    const double t = k * kStepUpdate_s;
    std::array<long long, 3> before{};
    for (int i = 0; i < 3; ++i) before[static_cast<size_t>(i)] = drivers[static_cast<size_t>(i)].steps();
    drivers[0].update(t, kRadius_mm * std::sin(w * t));
    drivers[1].update(t, kRadius_mm * (1.0 - std::cos(w * t)));
    drivers[2].update(t, 0.2 * t);  // slow Z
    for (int i = 0; i < 3; ++i) steps += std::llabs(drivers[static_cast<size_t>(i)].steps() - before[static_cast<size_t>(i)]);
    if (k % 20 == 0)
      for (auto& a : axes) reads += a.read_encoder_counts(t) != 0;
  }
  for (auto& a : axes) a.advance_to(n * kStepUpdate_s);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  (void)reads;
  return {"cartesian (3 gantry axes)", substep_hz, sim_s, wall, steps};
}

Row run_delta(double substep_hz, double sim_s) {
  DeltaPlantParams p;
  p.substep_hz = substep_hz;
  auto plant = std::move(DeltaPlant::create(p).value());
  const auto& geo = p.model.geometry;
  const Eigen::Vector3d q0 = feedloop::model::inverse_kinematics(geo, p.initial_nozzle_mm).value();
  std::array<StepDriver, 3> drivers{StepDriver(plant->carriage_port(0), p.mm_per_step),
                                    StepDriver(plant->carriage_port(1), p.mm_per_step),
                                    StepDriver(plant->carriage_port(2), p.mm_per_step)};
  const double w = kSpeed_mm_s / kRadius_mm;
  long long steps = 0;
  const auto t0 = Clock::now();
  const int n = static_cast<int>(sim_s / kStepUpdate_s);
  for (int k = 1; k <= n; ++k) {
    const double t = k * kStepUpdate_s;
    const Eigen::Vector3d pos = p.initial_nozzle_mm + Eigen::Vector3d(kRadius_mm * std::sin(w * t),
                                                                     kRadius_mm * (1.0 - std::cos(w * t)), 0.0);
    const Eigen::Vector3d q = feedloop::model::inverse_kinematics(geo, pos).value();
    for (int i = 0; i < 3; ++i) {
      const long long before = drivers[static_cast<size_t>(i)].steps();
      drivers[static_cast<size_t>(i)].update(t, q[i] - q0[i]);
      steps += std::llabs(drivers[static_cast<size_t>(i)].steps() - before);
    }
    if (k % 20 == 0)
      for (int i = 0; i < 3; ++i) (void)plant->carriage_port(i).read_encoder_counts(t);
  }
  plant->advance_to(n * kStepUpdate_s);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  return {"delta (3 carriages + effector)", substep_hz, sim_s, wall, steps};
}

}  // namespace

int main(int argc, char** argv) {
  const char* json_path = nullptr;
  double sim_s = 2.0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0 && i + 1 < argc) {
      json_path = argv[++i];
    } else if (std::strcmp(argv[i], "--seconds") == 0 && i + 1 < argc) {
      sim_s = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: %s [--json FILE] [--seconds S]\n", argv[0]);
      return 2;
    }
  }
  if (!(sim_s > 0.0)) {
    std::fprintf(stderr, "--seconds must be > 0\n");
    return 2;
  }
  std::vector<Row> rows;
  for (double hz : {20000.0, 40000.0}) {
    rows.push_back(run_cartesian(hz, sim_s));
    rows.push_back(run_delta(hz, sim_s));
  }
  std::printf("%-32s %10s %8s %9s %14s %10s\n", "machine", "substep_hz", "sim_s", "wall_s", "sim_s_per_wall_s",
              "steps");
  for (const Row& r : rows)
    std::printf("%-32s %10.0f %8.2f %9.3f %14.1f %10lld\n", r.machine.c_str(), r.substep_hz, r.sim_s, r.wall_s,
                r.sim_s / r.wall_s, r.steps);
  if (json_path) {
    FILE* f = std::fopen(json_path, "w");
    if (!f) {
      std::fprintf(stderr, "cannot write %s\n", json_path);
      return 1;
    }
    std::fprintf(f, "{\"benchmark\": \"sim\", \"rows\": [\n");
    for (size_t i = 0; i < rows.size(); ++i) {
      const Row& r = rows[i];
      std::fprintf(f,
                   "  {\"machine\": \"%s\", \"substep_hz\": %.0f, \"sim_s\": %.3f, \"wall_s\": %.6f, "
                   "\"sim_s_per_wall_s\": %.2f, \"steps\": %lld}%s\n",
                   r.machine.c_str(), r.substep_hz, r.sim_s, r.wall_s, r.sim_s / r.wall_s, r.steps,
                   i + 1 < rows.size() ? "," : "");
    }
    std::fprintf(f, "]}\n");
    std::fclose(f);
  }
  return 0;
}
