// Plant simulator speed: simulated seconds per wall-clock second for a Cartesian machine (three
// thesis gantry axes) and the delta (three carriages + rigid two-mass effector), each driven by
// ideal step pulses along a 100 mm/s circle with encoder reads at 1 kHz, at two RK4 substep rates.
// Usage: bench_sim [--json FILE] [--seconds S]
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
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
constexpr int kReadEvery = 20;  // encoder reads at 1 kHz

// One run: its speed and the ground truth at every encoder read (for the accuracy column).
struct Row {
  std::string machine;
  std::string substep;  // the rates in use, Hz (one per axis where they differ)
  double sim_s;
  double wall_s;
  long long steps;
  double max_dev_nm = 0.0;       // against the first rate's run of the same machine
  std::vector<double> truth_mm;  // carriage positions (and the delta's nozzle) at each read
};

std::string rates(const std::vector<double>& hz) {
  std::string out;
  for (size_t i = 0; i < hz.size(); ++i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%.0f", i > 0 ? "/" : "", hz[i]);
    out += buf;
  }
  return std::count(hz.begin(), hz.end(), hz[0]) == static_cast<std::ptrdiff_t>(hz.size())
             ? out.substr(0, out.find('/'))
             : out;
}

// Every effect of the identification's vocabulary on, at mid-range sizes of bench_ident_draws'
// draws (bench/ident_draws/README.md): what a simulator with "effects on" must keep up with.
void set_all_effects(GantryAxisParams& p) {
  auto& e = p.effects;
  e.coulomb_friction = {true, 2.0};
  e.backlash = {true, 30.0};
  e.periodic_position = {true, 33.93, 20.0};
  e.extra_resonance = {true, 60.0, 0.05, 0.15};
  e.time_delay = {true, 3.0};
  e.scale_error = {true, 1.004};
  // direction_dependent_stiffness 1.6: the belt anchor at L (r - 1) / (r + 1) (config/README.md)
  p.belt_x0_mm = p.belt_span_mm * 0.6 / 2.6;
}

// substep_hz 0: each plant's own choice (its fastest mode).
Row run_cartesian(double substep_hz, double sim_s, bool effects) {
  std::array<GantryAxisParams, 3> ps{feedloop::sim::thesis_x_axis(), feedloop::sim::thesis_y_axis(),
                                     feedloop::sim::thesis_x_axis()};
  std::vector<GantryAxis> axes;
  std::vector<double> hz;
  for (auto& p : ps) {
    if (effects) set_all_effects(p);
    p.substep_hz = substep_hz;
    axes.push_back(std::move(GantryAxis::create(p).value()));
    hz.push_back(axes.back().params().substep_hz);
  }
  std::vector<StepDriver> drivers;
  for (auto& a : axes) drivers.emplace_back(a, a.mm_per_step());
  const double w = kSpeed_mm_s / kRadius_mm;
  const int n = static_cast<int>(sim_s / kStepUpdate_s);
  std::vector<double> truth;
  truth.reserve(static_cast<size_t>(n / kReadEvery + 1) * 3);
  long long reads = 0, steps = 0;
  const auto t0 = Clock::now();
  for (int k = 1; k <= n; ++k) {
    const double t = k * kStepUpdate_s;
    std::array<long long, 3> before{};
    for (int i = 0; i < 3; ++i) before[static_cast<size_t>(i)] = drivers[static_cast<size_t>(i)].steps();
    drivers[0].update(t, kRadius_mm * std::sin(w * t));
    drivers[1].update(t, kRadius_mm * (1.0 - std::cos(w * t)));
    drivers[2].update(t, 0.2 * t);  // slow Z
    for (int i = 0; i < 3; ++i) steps += std::llabs(drivers[static_cast<size_t>(i)].steps() - before[static_cast<size_t>(i)]);
    if (k % kReadEvery == 0)
      for (auto& a : axes) {
        reads += a.read_encoder_counts(t) != 0;
        truth.push_back(a.carriage_mm());
      }
  }
  for (auto& a : axes) a.advance_to(n * kStepUpdate_s);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  (void)reads;
  return {effects ? "cartesian, all 7 effects on" : "cartesian (3 gantry axes)",
          rates(hz),
          sim_s,
          wall,
          steps,
          0.0,
          std::move(truth)};
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
  const int n = static_cast<int>(sim_s / kStepUpdate_s);
  std::vector<double> truth;
  truth.reserve(static_cast<size_t>(n / kReadEvery + 1) * 6);
  long long steps = 0;
  const auto t0 = Clock::now();
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
    if (k % kReadEvery == 0) {
      for (int i = 0; i < 3; ++i) {
        (void)plant->carriage_port(i).read_encoder_counts(t);
        truth.push_back(plant->carriage_mm(i));
      }
      const Eigen::Vector3d nozzle = plant->nozzle_mm();
      truth.insert(truth.end(), nozzle.data(), nozzle.data() + 3);
    }
  }
  plant->advance_to(n * kStepUpdate_s);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  return {"delta (3 carriages + effector)",
          rates({plant->params().substep_hz}),
          sim_s,
          wall,
          steps,
          0.0,
          std::move(truth)};
}

double max_dev_nm(const Row& a, const Row& ref) {
  double worst = 0.0;
  for (size_t i = 0; i < a.truth_mm.size() && i < ref.truth_mm.size(); ++i)
    worst = std::max(worst, std::abs(a.truth_mm[i] - ref.truth_mm[i]) * 1e6);
  return worst;
}

}  // namespace

int main(int argc, char** argv) {
  const char* json_path = nullptr;
  double sim_s = 2.0;
  // The first rate is the reference of the max_dev_nm column; 0 = each plant's own choice.
  std::vector<double> rates_hz{40000.0, 0.0};
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0 && i + 1 < argc) {
      json_path = argv[++i];
    } else if (std::strcmp(argv[i], "--seconds") == 0 && i + 1 < argc) {
      sim_s = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--substep-hz") == 0 && i + 1 < argc) {
      rates_hz.clear();
      for (const char* c = argv[++i]; *c != '\0';) {
        char* end = nullptr;
        rates_hz.push_back(std::strtod(c, &end));
        if (end == c) break;
        c = *end == ',' ? end + 1 : end;
      }
    } else {
      std::fprintf(stderr, "usage: %s [--json FILE] [--seconds S] [--substep-hz HZ,HZ,...]\n",
                   argv[0]);
      return 2;
    }
  }
  if (!(sim_s > 0.0)) {
    std::fprintf(stderr, "--seconds must be > 0\n");
    return 2;
  }
  for (double hz : rates_hz)
    if (hz != 0.0 && !(hz >= 1000.0 && hz <= 1e6)) {
      std::fprintf(stderr, "--substep-hz: each rate 0 (auto) or in [1000, 1e6]\n");
      return 2;
    }
  std::vector<Row> rows;
  for (int machine = 0; machine < 3; ++machine) {
    const size_t first = rows.size();
    for (double hz : rates_hz) {
      rows.push_back(machine == 2 ? run_delta(hz, sim_s) : run_cartesian(hz, sim_s, machine == 1));
      rows.back().max_dev_nm = max_dev_nm(rows.back(), rows[first]);
    }
  }
  std::printf("%-32s %-18s %8s %9s %16s %10s %10s\n", "machine", "substep_hz", "sim_s", "wall_s",
              "sim_s_per_wall_s", "steps", "max_dev_nm");
  for (const Row& r : rows)
    std::printf("%-32s %-18s %8.2f %9.3f %16.1f %10lld %10.3f\n", r.machine.c_str(),
                r.substep.c_str(), r.sim_s, r.wall_s, r.sim_s / r.wall_s, r.steps, r.max_dev_nm);
  if (json_path) {
    nlohmann::json out = {{"benchmark", "sim"}, {"rows", nlohmann::json::array()}};
    for (const Row& r : rows)
      out["rows"].push_back({{"machine", r.machine},
                             {"substep_hz", r.substep},  // a string: one rate, or one per axis
                             {"sim_s", r.sim_s},
                             {"wall_s", r.wall_s},
                             {"sim_s_per_wall_s", r.sim_s / r.wall_s},
                             {"steps", r.steps},
                             {"max_dev_nm", r.max_dev_nm}});
    if (!feedloop::bench::write_json(json_path, out)) return 1;
  }
  return 0;
}
