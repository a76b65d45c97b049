// feedloop-plant2: the second simulator as an External plant v1 (DESIGN.md), so that feedloop's
// built-in external plant support (sim/external_plant.hpp) drives it over pipes:
//
//   feedloop-plant2 [--seed N] [--effect KIND] [--carriage] [--truth]
//
// Every axis listed in the handshake is an independent Axis2 drawn by draw_axis(N + i, KIND) for
// the i-th axis (i from 0), at rest at the position the first period commands. Each period the
// commanded position held over the period is the one of the period's start (the previous line's,
// as a staircase is known at the period's end only), and the answer is the encoder's reading at
// t_s before quantisation (feedloop quantises): its interpolation error, scale error and transport
// delay are in it. --carriage answers the true carriage position instead. --truth writes the
// ground truth of every axis to stderr at the start.
//
// Exits 0 when stdin closes (at any point); 2 with a message on stderr on a malformed handshake or
// line, a time that is not k * period_s, or a start position the drawn machine cannot have.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "plant2/axis2.hpp"
#include "plant2/draw.hpp"
#include "plant2/protocol.hpp"

namespace {

using feedloop::plant2::Axis2;

int fail(const std::string& msg) {
  std::fprintf(stderr, "feedloop-plant2: %s\n", msg.c_str());
  return 2;
}

int usage(const std::string& msg) {
  std::fprintf(stderr,
               "feedloop-plant2: %s\nusage: feedloop-plant2 [--seed N] [--effect KIND] "
               "[--carriage] [--truth]\n  KIND: none periodic_position coulomb_friction backlash "
               "direction_dependent_stiffness extra_resonance time_delay scale_error\n",
               msg.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace feedloop::plant2;
  uint64_t seed = 1;
  EffectKind kind = EffectKind::none;
  bool carriage = false;
  bool truth = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seed" && i + 1 < argc) {
      char* end = nullptr;
      const std::string v = argv[++i];
      seed = std::strtoull(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0') return usage("--seed wants a non-negative integer");
    } else if (a == "--effect" && i + 1 < argc) {
      const auto k = effect_kind_from_name(argv[++i]);
      if (!k) return usage(std::string("unknown effect '") + argv[i] + "'");
      kind = *k;
    } else if (a == "--carriage") {
      carriage = true;
    } else if (a == "--truth") {
      truth = true;
    } else if (a == "--help" || a == "-h") {
      usage("External plant v1 (DESIGN.md) of the second simulator");
      return 0;
    } else {
      return usage("unknown option '" + a + "'");
    }
  }

  std::ios::sync_with_stdio(false);
  std::string line;
  if (!std::getline(std::cin, line)) return 0;  // closed before the handshake: nothing to do
  auto hs = parse_handshake(line);
  if (!hs) return fail(hs.error().message);
  const size_t n = hs->axes.size();
  const double period_s = hs->period_s;
  std::vector<Draw> draws;
  for (size_t i = 0; i < n; ++i) {
    draws.push_back(draw_axis(seed + i, kind));
    if (truth) {
      std::fprintf(stderr, "feedloop-plant2: axis %s seed %llu: %s\n", hs->axes[i].c_str(),
                   static_cast<unsigned long long>(seed + i), describe(draws.back()).c_str());
    }
  }
  std::fputs("ready\n", stdout);
  std::fflush(stdout);

  std::vector<Axis2> axes;
  axes.reserve(n);
  std::vector<double> u(n, 0.0), u_prev(n, 0.0), y(n, 0.0);
  std::string out;
  uint64_t k = 0;
  while (std::getline(std::cin, line)) {
    ++k;
    double t_s = 0.0;
    const std::string err = parse_period_line(line, n, &t_s, u.data());
    if (!err.empty()) return fail("line " + std::to_string(k + 1) + ": " + err);
    const double expect = static_cast<double>(k) * period_s;
    // Within the rounding of 9 significant digits, and well within a period.
    const double tol_s = std::min(0.25 * period_s, 1e-8 * std::max(1.0, expect));
    if (std::fabs(t_s - expect) > tol_s) {
      return fail("line " + std::to_string(k + 1) + ": t_s=" + std::to_string(t_s) +
                  ", expected period " + std::to_string(k) + " at " + std::to_string(expect));
    }
    if (k == 1) {
      // At rest at the start position the first period commands (the contract).
      for (size_t i = 0; i < n; ++i) {
        Axis2Params p = draws[i].params;
        p.start_m = u[i] * 1e-3;
        auto a = Axis2::create(p);
        if (!a) {
          return fail("axis " + hs->axes[i] + " cannot start at " + std::to_string(u[i]) +
                      " mm: " + a.error().message);
        }
        axes.push_back(std::move(a.value()));
        u_prev[i] = u[i];
      }
    }
    for (size_t i = 0; i < n; ++i) {
      axes[i].advance(u_prev[i] * 1e-3, period_s);
      y[i] = 1e3 * (carriage ? axes[i].carriage_m() : axes[i].measured_m());
      u_prev[i] = u[i];
    }
    format_answer(y.data(), n, &out);
    std::fwrite(out.data(), 1, out.size(), stdout);
    std::fflush(stdout);
  }
  return 0;
}
