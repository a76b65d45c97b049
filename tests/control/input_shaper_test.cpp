// InputShaper: Klipper's ZV / MZV / EI impulse sets (sum 1, residual vibration V at the design
// point from the impulses themselves), the centred FIR on the sampled reference (final value of
// a step, no lag on a ramp, exact against sum A_i r(t - t_i + t_c) for piecewise-linear r),
// residual vibration of a simulated second-order mode, corexy shaping in Cartesian space, delta
// shaping per carriage, and configuration errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include "control/input_shaper.hpp"
#include "engine/control_config.hpp"
#include "planner/kinematics.hpp"

namespace fc = feedloop::control;
using fc::ShaperType;
using CfgShaper = feedloop::config::ShaperType;

namespace {

constexpr double kPeriodS = 1e-3;
constexpr std::array<ShaperType, 3> kTypes = {ShaperType::zv, ShaperType::mzv, ShaperType::ei};

fc::Impulses impulses(ShaperType type, double f_hz, double zeta) {
  auto r = fc::make_impulses(type, f_hz, zeta);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  return r.ok() ? *r : fc::Impulses{};
}

// A shaper on joint 0 only (joint space, no linear map).
fc::InputShaper joint0_shaper(const fc::Impulses& s) {
  fc::InputShaperSetup setup;
  setup.period_s = kPeriodS;
  setup.shapers[0] = s;
  fc::InputShaper shaper;
  EXPECT_TRUE(shaper.configure(setup).ok());
  return shaper;
}

// Runs `shaper` on joint 0 with reference r(t): at cycle k it gets r(t_{k+P}) and returns u(t_k).
// Returns u(t_k) for k = k0 .. k1-1 (k0 may be negative: the shaped command starts t_c early).
std::vector<double> run_joint0(fc::InputShaper& shaper, const std::function<double(double)>& r, int k0, int k1) {
  const int p = shaper.preview_samples();
  fc::FeedforwardInput in;
  in.r_mm[0] = r((k0 + p) * kPeriodS);  // history as if r(t_{k0+P}) had been held (r is at rest there)
  shaper.reset(in);
  std::vector<double> u;
  fc::JointArray out{};
  for (int k = k0; k < k1; ++k) {
    in.r_mm[0] = r((k + p) * kPeriodS);
    shaper.step(in, out);
    u.push_back(out[0]);
  }
  return u;
}

// sum_i A_i r(t - t_i + t_c): what the shaper must produce for r linear between samples.
double shaped_exact(const fc::Impulses& s, const std::function<double(double)>& r, double t) {
  const double t_c = fc::centre_time_s(s);
  double y = 0.0;
  for (int i = 0; i < s.n; ++i) y += s.a[i] * r(t - s.t_s[i] + t_c);
  return y;
}

}  // namespace

TEST(InputShaper, ImpulseSumsAreOne) {
  for (ShaperType type : kTypes)
    for (double zeta : {0.0, 0.05, 0.1, 0.2, 0.4})
      for (double f : {20.0, 40.0, 73.3}) {
        const fc::Impulses s = impulses(type, f, zeta);
        double sum = 0.0;
        for (int i = 0; i < s.n; ++i) {
          sum += s.a[i];
          EXPECT_GT(s.a[i], 0.0);
          if (i > 0) {
            EXPECT_GT(s.t_s[i], s.t_s[i - 1]);
          }
        }
        EXPECT_NEAR(sum, 1.0, 1e-12) << fc::shaper_name(type) << " zeta " << zeta;
        EXPECT_EQ(s.t_s[0], 0.0);
        // Duration: ZV half a damped period, MZV 3/4, EI one.
        const double t_d = 1.0 / (f * std::sqrt(1.0 - zeta * zeta));
        const double expected = type == ShaperType::zv ? 0.5 : type == ShaperType::mzv ? 0.75 : 1.0;
        EXPECT_NEAR(s.t_s[s.n - 1], expected * t_d, 1e-12);
      }
}

TEST(InputShaper, ResidualVibrationAtDesignPoint) {
  fc::Impulses none;
  none.n = 1;
  none.a[0] = 1.0;
  EXPECT_NEAR(fc::residual_vibration(none, 40.0, 0.1), 1.0, 1e-12);
  for (double zeta : {0.0, 0.05, 0.1, 0.2}) {
    for (double f : {25.0, 40.0, 61.0}) {
      EXPECT_LT(fc::residual_vibration(impulses(ShaperType::zv, f, zeta), f, zeta), 1e-9);
      EXPECT_LT(fc::residual_vibration(impulses(ShaperType::mzv, f, zeta), f, zeta), 1e-9);
      const double v_ei = fc::residual_vibration(impulses(ShaperType::ei, f, zeta), f, zeta);
      // Klipper's EI curve fit only approximates its V_tol = 5 % (measured 4.88-5.06 % here).
      EXPECT_LE(v_ei, 0.051) << "zeta " << zeta;
      EXPECT_GT(v_ei, 0.03);  // EI is designed to V_tol = 5 % at f, not 0
    }
  }
  // Robustness to a 20 % frequency error (the point of MZV and EI): EI < MZV < ZV.
  const double f = 40.0, zeta = 0.1;
  for (double f_mode : {0.8 * f, 1.2 * f}) {
    const double v_zv = fc::residual_vibration(impulses(ShaperType::zv, f, zeta), f_mode, zeta);
    const double v_mzv = fc::residual_vibration(impulses(ShaperType::mzv, f, zeta), f_mode, zeta);
    const double v_ei = fc::residual_vibration(impulses(ShaperType::ei, f, zeta), f_mode, zeta);
    EXPECT_LT(v_ei, v_mzv);
    EXPECT_LT(v_mzv, v_zv);
    EXPECT_LT(v_ei, 0.06);
  }
}

TEST(InputShaper, ZvMatchesClosedForm) {
  // Undamped ZV: two halves half a period apart; damped: A2/A1 = K = exp(-zeta pi / sqrt(1-zeta^2)).
  const fc::Impulses s0 = impulses(ShaperType::zv, 50.0, 0.0);
  EXPECT_NEAR(s0.a[0], 0.5, 1e-15);
  EXPECT_NEAR(s0.t_s[1], 0.01, 1e-15);
  const fc::Impulses s = impulses(ShaperType::zv, 50.0, 0.1);
  EXPECT_NEAR(s.a[1] / s.a[0], std::exp(-0.1 * std::numbers::pi / std::sqrt(0.99)), 1e-12);
}

TEST(InputShaper, PreviewIsCeilOfCentreTime) {
  for (ShaperType type : kTypes) {
    const fc::Impulses s = impulses(type, 37.0, 0.1);
    fc::InputShaper shaper = joint0_shaper(s);
    const double t_c = fc::centre_time_s(s);
    EXPECT_EQ(shaper.preview_samples(), static_cast<int>(std::ceil(t_c / kPeriodS)));
    EXPECT_GT(t_c, 0.0);
    EXPECT_LT(t_c, s.t_s[s.n - 1]);
  }
}

TEST(InputShaper, StepFinalValueEqualsInput) {
  for (ShaperType type : kTypes) {
    const fc::Impulses s = impulses(type, 40.0, 0.1);
    fc::InputShaper shaper = joint0_shaper(s);
    auto step = [](double t) { return t >= 0.0 ? 10.0 : 0.0; };
    const std::vector<double> u = run_joint0(shaper, step, -100, 200);
    EXPECT_NEAR(u.front(), 0.0, 1e-15);
    EXPECT_NEAR(u.back(), 10.0, 1e-12) << fc::shaper_name(type);
    // Monotone (all A_i > 0) and only moving within the shaper's span around t = 0.
    for (std::size_t i = 1; i < u.size(); ++i) EXPECT_GE(u[i], u[i - 1] - 1e-12);
  }
}

TEST(InputShaper, RampHasNoLagAndMatchesExactFormula) {
  for (ShaperType type : kTypes) {
    const fc::Impulses s = impulses(type, 33.0, 0.15);  // impulse times off the 1 ms grid
    fc::InputShaper shaper = joint0_shaper(s);
    // Trapezoid-ish piecewise-linear reference with corners on sample instants: exact under
    // linear interpolation.
    auto r = [](double t) {
      const double a = std::clamp(t, 0.0, 0.1), b = std::clamp(t - 0.1, 0.0, 0.2), c = std::clamp(t - 0.3, 0.0, 0.05);
      return 100.0 * a + 50.0 * b - 40.0 * c;  // 100 mm/s, 50 mm/s, -40 mm/s, then rest
    };
    const std::vector<double> u = run_joint0(shaper, r, -60, 450);
    double worst = 0.0;
    for (int k = -60; k < 450; ++k)
      worst = std::max(worst, std::abs(u[k + 60] - shaped_exact(s, r, k * kPeriodS)));
    EXPECT_LT(worst, 1e-9) << fc::shaper_name(type);
    // Centred: in the middle of the 100 mm/s ramp (t = 50 ms, farther than the span from the
    // corners) the shaped command equals the reference, no lag.
    EXPECT_NEAR(u[50 + 60], r(0.05), 1e-9);
    EXPECT_NEAR(u[449 + 60], r(0.449), 1e-12);
  }
}

TEST(InputShaper, ReducesResidualVibrationOfSimulatedMode) {
  // Carriage as a lightly damped mode at 40 Hz, zeta 0.02, driven by the (linearly
  // interpolated) motor command: y'' = w^2 (u - y) - 2 zeta w y'. An 11.25 mm move at 100 mm/s
  // with instant speed changes, 4.5 mode periods long so that start and stop ringing add up.
  const double f = 40.0, zeta = 0.02, w = 2.0 * std::numbers::pi * f;
  auto r = [](double t) { return 100.0 * std::clamp(t, 0.0, 0.1125); };
  auto residual = [&](const std::vector<double>& u, int k0) {
    double y = 0.0, v = 0.0, worst = 0.0;
    const int sub = 20;
    const double h = kPeriodS / sub;
    for (std::size_t i = 0; i + 1 < u.size(); ++i) {
      for (int j = 0; j < sub; ++j) {  // RK4 with u linear over the period
        auto uu = [&](double s) { return u[i] + (u[i + 1] - u[i]) * s / kPeriodS; };
        auto acc = [&](double s, double yy, double vv) { return w * w * (uu(s) - yy) - 2 * zeta * w * vv; };
        const double s0 = j * h;
        const double k1y = v, k1v = acc(s0, y, v);
        const double k2y = v + 0.5 * h * k1v, k2v = acc(s0 + 0.5 * h, y + 0.5 * h * k1y, v + 0.5 * h * k1v);
        const double k3y = v + 0.5 * h * k2v, k3v = acc(s0 + 0.5 * h, y + 0.5 * h * k2y, v + 0.5 * h * k2v);
        const double k4y = v + h * k3v, k4v = acc(s0 + h, y + h * k3y, v + h * k3v);
        y += h / 6 * (k1y + 2 * k2y + 2 * k3y + k4y);
        v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
      }
      const double t = (static_cast<int>(i) + 1 + k0) * kPeriodS;
      if (t > 0.16) worst = std::max(worst, std::abs(y - 11.25));  // after the move and the shaper
    }
    return worst;
  };
  std::vector<double> unshaped;
  for (int k = -50; k < 400; ++k) unshaped.push_back(r(k * kPeriodS));
  const double base = residual(unshaped, -50);
  EXPECT_GT(base, 0.3);  // the bare move rings (measured 0.47 mm)
  for (ShaperType type : kTypes) {
    fc::InputShaper shaper = joint0_shaper(impulses(type, f, zeta));
    const double ratio = residual(run_joint0(shaper, r, -50, 400), -50) / base;
    std::printf("%s: residual %.4f mm of %.4f mm unshaped (ratio %.4f)\n", fc::shaper_name(type), ratio * base, base, ratio);
    // Measured: ZV 0.3 %, MZV 0.1 % (the sampled, interpolated shaper), EI 5.5 % (its 5 % design
    // tolerance at the design point).
    EXPECT_LT(ratio, type == ShaperType::ei ? 0.06 : 0.01) << fc::shaper_name(type) << " ratio " << ratio;
  }
}

TEST(InputShaper, CorexyShapesCartesianAxesSeparately) {
  feedloop::planner::PlannerConfig cfg;
  cfg.kinematics = feedloop::planner::KinematicsKind::corexy;
  auto kin = feedloop::planner::make_kinematics(cfg);
  feedloop::config::ShaperConfig sc;
  sc.type = CfgShaper::zv;
  sc.freq_hz = 50.0;
  sc.axes.push_back({"x", CfgShaper::mzv, 35.0, 0.1});
  auto setup = feedloop::engine::input_shaper_setup(sc, *kin, kPeriodS);
  ASSERT_TRUE(setup.ok()) << setup.error().message;
  ASSERT_TRUE(setup->linear_map.has_value());
  EXPECT_FALSE(setup->shapers[2].has_value());  // z passes through
  fc::InputShaper shaper;
  ASSERT_TRUE(shaper.configure(*setup).ok());
  const fc::Impulses sx = *setup->shapers[0], sy = *setup->shapers[1];
  EXPECT_EQ(sx.n, 3);  // the x override: MZV
  EXPECT_EQ(sy.n, 2);  // y from the common values: ZV
  EXPECT_EQ(shaper.preview_samples(),
            static_cast<int>(std::ceil(std::max(fc::centre_time_s(sx), fc::centre_time_s(sy)) / kPeriodS)));

  auto x = [](double t) { return 80.0 * std::clamp(t, 0.0, 0.1); };
  auto y = [](double t) { return -60.0 * std::clamp(t - 0.05, 0.0, 0.1); };
  auto z = [](double t) { return 0.2 + 2.0 * std::clamp(t, 0.0, 0.1); };
  const auto m = kin->linear_map();
  const int p = shaper.preview_samples();
  fc::FeedforwardInput in;
  auto fill = [&](double t) {
    in.nozzle_mm = {x(t), y(t), z(t)};
    const auto q = kin->inverse(in.nozzle_mm);
    for (int j = 0; j < 3; ++j) in.r_mm[j] = q[j];
    in.r_mm[3] = 5.0 * std::max(t, 0.0);  // extruder
  };
  fill((-50 + p) * kPeriodS);
  shaper.reset(in);
  double worst = 0.0;
  fc::JointArray u{};
  for (int k = -50; k < 300; ++k) {
    const double t = k * kPeriodS;
    fill(t + p * kPeriodS);
    shaper.step(in, u);
    const std::array<double, 3> xs = {shaped_exact(sx, x, t), shaped_exact(sy, y, t), z(t)};
    for (int i = 0; i < 3; ++i) {
      double q = 0.0;
      for (int j = 0; j < 3; ++j) q += m[i][j] * xs[j];
      worst = std::max(worst, std::abs(u[i] - q));
    }
    worst = std::max(worst, std::abs(u[3] - 5.0 * std::max(t, 0.0)));  // extruder: delayed, not shaped
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(InputShaper, DeltaShapesEachCarriage) {
  feedloop::planner::PlannerConfig cfg;
  cfg.kinematics = feedloop::planner::KinematicsKind::delta;
  auto kin = feedloop::planner::make_kinematics(cfg);
  feedloop::config::ShaperConfig sc;
  sc.type = CfgShaper::ei;
  sc.freq_hz = 45.0;
  sc.axes.push_back({"B", CfgShaper::zv, 30.0, 0.05});
  auto setup = feedloop::engine::input_shaper_setup(sc, *kin, kPeriodS);
  ASSERT_TRUE(setup.ok()) << setup.error().message;
  EXPECT_FALSE(setup->linear_map.has_value());
  ASSERT_TRUE(setup->shapers[0] && setup->shapers[1] && setup->shapers[2]);
  EXPECT_EQ(setup->shapers[1]->n, 2);
  EXPECT_NEAR(setup->shapers[1]->t_s[1], 0.5 / (30.0 * std::sqrt(1 - 0.05 * 0.05)), 1e-12);
  EXPECT_NEAR(setup->shapers[0]->t_s[2], 1.0 / (45.0 * std::sqrt(1 - 0.01)), 1e-12);
}

TEST(InputShaper, RejectsBadParameters) {
  auto f0 = fc::make_impulses(ShaperType::zv, 0.0, 0.1);
  ASSERT_FALSE(f0.ok());
  EXPECT_NE(f0.error().message.find("freq_hz"), std::string::npos);
  EXPECT_FALSE(fc::make_impulses(ShaperType::mzv, 40.0, 1.0).ok());
  EXPECT_FALSE(fc::make_impulses(ShaperType::mzv, 40.0, -0.1).ok());
  auto ei = fc::make_impulses(ShaperType::ei, 40.0, 0.5);
  ASSERT_FALSE(ei.ok());
  EXPECT_NE(ei.error().message.find("0.4"), std::string::npos);

  feedloop::planner::PlannerConfig cfg;
  auto kin = feedloop::planner::make_kinematics(cfg);
  feedloop::config::ShaperConfig sc;
  sc.axes.push_back({"y", CfgShaper::zv, -3.0, 0.1});
  auto setup = feedloop::engine::input_shaper_setup(sc, *kin, kPeriodS);
  ASSERT_FALSE(setup.ok());
  EXPECT_NE(setup.error().message.find("axis y"), std::string::npos);

  fc::InputShaper shaper;
  fc::InputShaperSetup bad;
  bad.period_s = 0.0;
  EXPECT_FALSE(shaper.configure(bad).ok());
  bad.period_s = kPeriodS;
  fc::Impulses unnormalised;
  unnormalised.n = 2;
  unnormalised.a = {1.0, 1.0};
  unnormalised.t_s = {0.0, 0.01};
  bad.shapers[0] = unnormalised;
  EXPECT_FALSE(shaper.configure(bad).ok());
}
