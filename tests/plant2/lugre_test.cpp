// LuGre friction of the second simulator (plant2/lugre.hpp): the steady state is the Stribeck
// curve plus the viscous term; below breakaway a mass sticks (pre-sliding only), above it slides.
#include <gtest/gtest.h>

#include <cmath>

#include "plant2/lugre.hpp"

namespace feedloop::plant2 {
namespace {

LuGreParams params() {
  LuGreParams p;
  p.coulomb_n = 2.0;
  p.static_n = 3.0;
  p.stribeck_m_s = 2e-3;
  p.sigma0_n_m = 6e5;  // 5 um of pre-sliding at breakaway
  p.sigma1_n_s_m = 300.0;
  p.sigma2_n_s_m = 20.0;
  return p;
}

TEST(LuGre, SteadyStateForceIsTheStribeckCurvePlusViscous) {
  for (double v : {-0.1, -5e-3, -1e-3, 5e-4, 1e-3, 2e-3, 4e-3, 0.02, 0.3}) {
    LuGre f(params());
    for (int i = 0; i < 20000; ++i) f.advance(v, 1e-5);  // 0.2 s at constant speed
    const double s = v / 2e-3;
    const double expect = (2.0 + 1.0 * std::exp(-s * s)) * (v > 0 ? 1.0 : -1.0) + 20.0 * v;
    EXPECT_NEAR(f.force_n(v), expect, 1e-6 * std::fabs(expect)) << "v = " << v;
    EXPECT_NEAR(f.stribeck_n(v), 2.0 + std::exp(-s * s), 1e-12);
  }
}

// A 0.5 kg mass pushed by a constant force from rest: sticks below F_s, slides above.
double pushed_distance_m(double force_n, double* speed_end) {
  LuGre f(params());
  double x = 0.0, v = 0.0;
  const double m = 0.5, dt = 2e-6;
  for (int i = 0; i < 250000; ++i) {  // 0.5 s
    const double a = (force_n - f.force_n(v)) / m;
    v += a * dt;
    x += v * dt;
    f.advance(v, dt);
  }
  *speed_end = v;
  return x;
}

TEST(LuGre, SticksBelowBreakawayAndSlidesAbove) {
  double v_end = 0.0;
  // 90 % of F_c applied as a step: the bristles deflect (z = F / sigma0 = 3 um), the step's
  // transient slips a few um more, and the mass comes to rest for good.
  // (Between F_c and F_s LuGre creeps into sliding where g(v) + sigma2 v = F: its breakaway is
  // dynamic.)
  const double stick = pushed_distance_m(0.9 * 2.0, &v_end);
  EXPECT_LT(std::fabs(stick), 20e-6) << stick;
  EXPECT_GT(stick, 2e-6) << stick;
  EXPECT_LT(std::fabs(v_end), 1e-9);
  // 120 % of F_s: it breaks away and accelerates (at most (3.6 - 2) / 0.5 = 3.2 m/s^2).
  const double slide = pushed_distance_m(1.2 * 3.0, &v_end);
  EXPECT_GT(slide, 0.01) << slide;
  EXPECT_GT(v_end, 0.02);
}

}  // namespace
}  // namespace feedloop::plant2
