// bench_model: how far apart the delta paper's force transformation (Eq. 25/69) and the
// virtual-work form put the predicted FRFs (Eq. 29, Table I parameters) at the four validation
// positions, and how long the model's operations take (FRF grids, state space + ZOH, filter step).
// Prints a table; --json FILE writes the same figures as JSON.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "model/delta_lpv.hpp"
#include "model/discrete.hpp"
#include "model/frf_metrics.hpp"

namespace fm = feedloop::model;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Frequency of the largest |G_ii| on the grid.
double peak_hz(const fm::FrfSet& set, int i) {
  double best = 0.0, f = 0.0;
  for (int k = 0; k < set.size(); ++k) {
    const double a = std::abs(set.h[static_cast<size_t>(k)](i, i));
    if (a > best) {
      best = a;
      f = set.freq_hz[static_cast<size_t>(k)];
    }
  }
  return f;
}

struct Row {
  std::string pos;
  char carriage;
  double peak_paper_hz, peak_vw_hz, acc_mag_pct, acc_phase_pct;
};

}  // namespace

int main(int argc, char** argv) {
  std::string json_path;
  for (int a = 1; a < argc; ++a) {
    if (std::strcmp(argv[a], "--json") == 0 && a + 1 < argc) {
      json_path = argv[++a];
    } else {
      std::fprintf(stderr, "usage: %s [--json FILE]\n", argv[0]);
      return 2;
    }
  }
  const fm::DeltaParams params;  // Table I
  auto paper = fm::DeltaLpvModel::create(params, fm::ForceTransform::Paper);
  auto vw = fm::DeltaLpvModel::create(params, fm::ForceTransform::VirtualWork);
  if (!paper || !vw) return 1;
  const fm::FrequencyGrid grid;
  const Eigen::Vector3d positions[] = {{0, 0, 30}, {-80, 0, 30}, {40, -69, 30}, {40, 69, 30}};

  std::vector<Row> rows;
  std::printf("Delta FRFs, Table I, 2-125 Hz: paper form (Eq. 25/69) against virtual work (VW as reference)\n");
  std::printf("%-14s %-3s %12s %10s %12s %14s\n", "position_mm", "car", "peak_paper", "peak_vw",
              "mu_acc_mag%", "mu_acc_phase%");
  for (const auto& x : positions) {
    auto sp = paper->frf(x, grid);
    auto sv = vw->frf(x, grid);
    if (!sp || !sv) return 1;
    auto mag = fm::mu_acc(*sv, *sp, fm::FrfQuantity::Magnitude);
    auto ph = fm::mu_acc(*sv, *sp, fm::FrfQuantity::Phase);
    if (!mag || !ph) return 1;
    char pos[64];
    std::snprintf(pos, sizeof pos, "(%g,%g,%g)", x.x(), x.y(), x.z());
    for (int i = 0; i < 3; ++i) {
      Row r{pos, static_cast<char>('A' + i), peak_hz(*sp, i), peak_hz(*sv, i), (*mag)(i, i), (*ph)(i, i)};
      std::printf("%-14s %-3c %9.1f Hz %7.1f Hz %12.1f %14.1f\n", r.pos.c_str(), r.carriage, r.peak_paper_hz,
                  r.peak_vw_hz, r.acc_mag_pct, r.acc_phase_pct);
      rows.push_back(r);
    }
  }

  // Timings.
  const int n_frf = 200;
  auto t0 = Clock::now();
  double sink = 0.0;
  for (int k = 0; k < n_frf; ++k) {
    auto s = paper->frf(positions[k % 4], grid);
    sink += std::abs(s->h[0](0, 0));
  }
  const double frf_grid_ms = seconds_since(t0) / n_frf * 1e3;

  const int n_zoh = 200;
  t0 = Clock::now();
  fm::DiscreteStateSpace last;
  for (int k = 0; k < n_zoh; ++k) {
    auto op = paper->at(positions[k % 4]);
    auto ss = paper->state_space(*op);
    auto d = fm::discretize_zoh(*ss, 1e-3);
    last = *d;
  }
  const double zoh_ms = seconds_since(t0) / n_zoh * 1e3;

  fm::DiscreteLtiFilter filter;
  if (!filter.configure(last)) return 1;
  const int n_step = 1000000;
  double u[3] = {0, 0, 0}, y[3];
  t0 = Clock::now();
  for (int k = 0; k < n_step; ++k) {
    u[0] = (k % 1000) * 1e-3;
    filter.step(u, y);
    sink += y[0];
  }
  const double step_ns = seconds_since(t0) / n_step * 1e9;

  std::printf("\n%-44s %10s\n", "operation", "time");
  std::printf("%-44s %7.3f ms\n", "Eq. 29 FRF on the 247-point grid (one position)", frf_grid_ms);
  std::printf("%-44s %7.3f ms\n", "state space (18 states) + ZOH at 1 kHz", zoh_ms);
  std::printf("%-44s %7.1f ns\n", "discrete 3x3 filter step (18 states)", step_ns);
  if (sink == 42.0) std::printf(" ");  // keep the work observable

  if (!json_path.empty()) {
    nlohmann::json j = {{"frf_forms", nlohmann::json::array()},
                        {"timing",
                         {{"frf_grid_ms", frf_grid_ms},
                          {"state_space_zoh_ms", zoh_ms},
                          {"filter_step_ns", step_ns}}}};
    for (const Row& r : rows)
      j["frf_forms"].push_back({{"position_mm", r.pos},
                                {"carriage", std::string(1, r.carriage)},
                                {"peak_paper_hz", r.peak_paper_hz},
                                {"peak_vw_hz", r.peak_vw_hz},
                                {"mu_acc_mag_pct", r.acc_mag_pct},
                                {"mu_acc_phase_pct", r.acc_phase_pct}});
    if (!feedloop::bench::write_json(json_path, j)) return 1;
  }
  return 0;
}
