// The second simulator's axis (plant2/axis2.hpp): the lowest mode against the thesis's two-mass
// model (Eq. 13) with the belt's position-dependent stiffness, microstep error and detent ripple
// at their periods and sizes, the encoder's interpolation error and delay, backlash as lost
// motion, rest without drift, and the simulation's speed.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <vector>

#include <Eigen/Dense>

#include "plant2/axis2.hpp"
#include "tests/plant2/common.hpp"

namespace feedloop::plant2 {
namespace {

using p2test::amplitude_at;
using p2test::quiet_params;

constexpr double kTwoPi = 6.283185307179586;
constexpr double kPi = 3.141592653589793;

// Thesis Eq. 13 (two masses, e = 1): m_1 = J / r^2 plus the belt on the pulley, k_1 = T_max n_r /
// r^2 (Eq. 14), k_2 the belt's stiffness at x (k^ / l_1 + k^ / (l_2 + l_3)), m_2 the carriage plus
// a third of its spans' belt mass (Rayleigh). The lower root of det(K - w^2 M) = 0, in Hz.
double two_mass_lowest_hz(const Axis2Params& p, double x_m) {
  const double r = p.stepper.pulley_radius_m;
  const double m1 = p.stepper.rotor_inertia_kg_m2 / (r * r) + p.belt.linear_density_kg_m * kPi * r;
  const double k1 = p.stepper.holding_torque_nm * p.stepper.rotor_teeth / (r * r);
  const double k2 = Axis2::belt_stiffness_n_m(p.belt, x_m);
  double l[3];
  Axis2::span_lengths(p.belt, x_m, l);
  const double m2 = p.carriage.mass_kg + p.belt.linear_density_kg_m * (l[0] + l[1] + l[2]) / 3.0;
  const double a = m1 * m2, b = -(m1 * k2 + m2 * (k1 + k2)), c = k1 * k2;
  const double w2 = (-b - std::sqrt(b * b - 4.0 * a * c)) / (2.0 * a);
  return std::sqrt(w2) / kTwoPi;
}

// The frequency of the largest spectral peak of y (Hann window) between lo and hi Hz.
double peak_hz(const std::vector<double>& y, double fs, double lo, double hi) {
  const size_t n = y.size();
  double mean = 0.0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(n);
  std::vector<double> w(n);
  for (size_t i = 0; i < n; ++i)
    w[i] = (y[i] - mean) * (0.5 - 0.5 * std::cos(kTwoPi * static_cast<double>(i) / (n - 1)));
  auto power = [&](double f) {
    double s = 0.0, c = 0.0;
    const double d = kTwoPi * f / fs;
    for (size_t i = 0; i < n; ++i) {
      s += w[i] * std::sin(d * static_cast<double>(i));
      c += w[i] * std::cos(d * static_cast<double>(i));
    }
    return s * s + c * c;
  };
  double best = lo, best_p = -1.0;
  for (double f = lo; f <= hi; f += 0.25) {
    const double pw = power(f);
    if (pw > best_p) best_p = pw, best = f;
  }
  const double centre = best;
  for (double f = centre - 0.3; f <= centre + 0.3; f += 0.01) {
    const double pw = power(f);
    if (pw > best_p) best_p = pw, best = f;
  }
  return best;
}

TEST(Axis2, LowestModeMatchesTheTwoMassModelAndFollowsThePosition) {
  Axis2Params p = quiet_params();
  p.stepper.field_damping_nm_s_rad = 0.0;
  p.stepper.bearing_damping_nm_s_rad = 0.0;
  p.belt.span_damping_s = 0.0;
  double freq_near = 0.0, freq_far = 0.0;
  for (double x : {0.010, 0.280}) {
    p.start_m = x;
    auto a = Axis2::create(p);
    ASSERT_TRUE(a.ok()) << a.error().message;
    Axis2& axis = a.value();
    const double fs = 4000.0;
    std::vector<double> y;
    const double u = x + 5e-6;  // a 5 um jump of the field: rings the modes
    for (int i = 0; i < 16000; ++i) {
      axis.advance(u, 1.0 / fs);
      y.push_back(axis.carriage_m());
    }
    const double measured = peak_hz(y, fs, 10.0, 400.0);
    const double expect = two_mass_lowest_hz(p, x);
    EXPECT_NEAR(measured, expect, 0.03 * expect) << "x = " << x;
    std::printf("x = %.3f m: lowest mode %.2f Hz, two-mass estimate %.2f Hz\n", x, measured,
                expect);
    (x < 0.1 ? freq_near : freq_far) = measured;
  }
  // Near the pulley the short span is stiffer: the mode is higher there.
  EXPECT_GT(freq_near, 1.3 * freq_far);
}

// Carriage minus command at a constant slow speed, demodulated at one spatial period.
double ripple_amplitude_m(const Axis2Params& p, double period_m) {
  auto a = Axis2::create(p);
  EXPECT_TRUE(a.ok());
  Axis2& axis = a.value();
  const double speed = 1e-3;  // 1 mm/s: the ripple at <= 6 Hz, far below the modes
  const double dt = 1e-4;
  const double step_m = kTwoPi * p.stepper.pulley_radius_m / (4.0 * 50.0 * 16.0);
  std::vector<double> err, ph;
  const double settle_s = 0.3;
  const int cycles = 8;
  const double run_s = settle_s + cycles * period_m / speed;
  for (double t = dt; t <= run_s + 1e-12; t += dt) {
    const double u = p.start_m + speed * t;
    axis.advance(std::round(u / step_m) * step_m, dt);
    if (t > settle_s) {
      err.push_back(axis.carriage_m() - u);
      ph.push_back(kTwoPi * u / period_m);
    }
  }
  return amplitude_at(err, ph);
}

TEST(Axis2, MicrostepErrorShowsAtItsPeriodsWithItsSize) {
  Axis2Params p = quiet_params();
  const double r = p.stepper.pulley_radius_m;
  const double full_step_m = kTwoPi * r / 200.0;
  const double electrical_m = kTwoPi * r / 50.0;
  p.stepper.microstep_err4_rad = 8e-6 * 50.0 / r;  // 8 um quasi-static at the carriage
  p.stepper.microstep_phase4_rad = 0.7;
  const double a4 = ripple_amplitude_m(p, full_step_m);
  EXPECT_NEAR(a4, 8e-6, 0.8e-6);
  EXPECT_LT(ripple_amplitude_m(p, electrical_m), 0.3e-6);  // nothing at the other period
  p.stepper.microstep_err4_rad = 0.0;
  p.stepper.microstep_err1_rad = 5e-6 * 50.0 / r;
  const double a1 = ripple_amplitude_m(p, electrical_m);
  EXPECT_NEAR(a1, 5e-6, 0.5e-6);
  std::printf("microstep ripple: %.2f um (8 drawn) per full step, %.2f um (5 drawn) per cycle\n",
              a4 * 1e6, a1 * 1e6);
}

TEST(Axis2, DetentTorqueRipplesOncePerFullStep) {
  Axis2Params p = quiet_params();
  p.stepper.detent_torque_nm = 0.05 * p.stepper.holding_torque_nm;
  const double r = p.stepper.pulley_radius_m;
  // Quasi-static: the detent torque displaces the rotor against the field's stiffness T_max n_r.
  const double expect = r * 0.05 / 50.0;
  const double amp = ripple_amplitude_m(p, kTwoPi * r / 200.0);
  EXPECT_NEAR(amp, expect, 0.1 * expect);
  EXPECT_LT(ripple_amplitude_m(p, kTwoPi * r / 50.0), 0.1 * expect);
}

TEST(Axis2, PulleyRunoutRipplesOncePerPulleyTurn) {
  Axis2Params p = quiet_params();
  p.stepper.runout_m = 25e-6;
  p.stepper.runout_phase_rad = 2.0;
  p.start_m = 0.02;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  const double period_m = kTwoPi * p.stepper.pulley_radius_m;  // 33.93 mm
  const double speed = 0.02;
  std::vector<double> err, ph;
  const double dt = 5e-4;
  const double settle_s = 0.2;
  for (double t = dt; t <= settle_s + 7.0 * period_m / speed + 1e-9; t += dt) {
    const double u = p.start_m + speed * t;
    axis.advance(u, dt);
    if (t > settle_s) {
      err.push_back(axis.carriage_m() - u);
      ph.push_back(kTwoPi * (u - p.start_m) / period_m);
    }
  }
  EXPECT_NEAR(amplitude_at(err, ph), 25e-6, 1.5e-6);
}

TEST(Axis2, ExtraResonanceAddsAModeWhereTheThreeMassModelPutsIt) {
  Axis2Params p = quiet_params();
  p.stepper.field_damping_nm_s_rad = 0.0;
  p.stepper.bearing_damping_nm_s_rad = 0.0;
  p.belt.span_damping_s = 0.0;
  p.carriage.extra_mass_kg = 0.12;
  p.carriage.extra_freq_hz = 90.0;
  p.carriage.extra_damping_ratio = 0.0;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  const double fs = 4000.0;
  std::vector<double> y;
  for (int i = 0; i < 16000; ++i) {
    axis.advance(p.start_m + 5e-6, 1.0 / fs);
    y.push_back(axis.carriage_m());
  }
  // Rotor (J / r^2 plus the belt on the pulley), carriage, extra mass: thesis Eq. 13 with a third
  // mass on the carriage.
  const double r = p.stepper.pulley_radius_m;
  double l[3];
  Axis2::span_lengths(p.belt, p.start_m, l);
  const double m1 = p.stepper.rotor_inertia_kg_m2 / (r * r) + p.belt.linear_density_kg_m * kPi * r;
  const double m2 = p.carriage.mass_kg + p.belt.linear_density_kg_m * (l[0] + l[1] + l[2]) / 3.0;
  const double m3 = 0.12;
  const double k1 = p.stepper.holding_torque_nm * p.stepper.rotor_teeth / (r * r);
  const double k2 = Axis2::belt_stiffness_n_m(p.belt, p.start_m);
  const double k3 = m3 * std::pow(kTwoPi * 90.0, 2);
  Eigen::Matrix3d K, M = Eigen::Vector3d(m1, m2, m3).asDiagonal();
  K << k1 + k2, -k2, 0.0, -k2, k2 + k3, -k3, 0.0, -k3, k3;
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix3d> es(K, M);
  const double f_low = std::sqrt(es.eigenvalues()(0)) / kTwoPi;
  const double f_mid = std::sqrt(es.eigenvalues()(1)) / kTwoPi;
  const double got_low = peak_hz(y, fs, 0.85 * f_low, 1.15 * f_low);
  const double got_mid = peak_hz(y, fs, 0.85 * f_mid, 1.15 * f_mid);
  EXPECT_NEAR(got_low, f_low, 0.03 * f_low);
  EXPECT_NEAR(got_mid, f_mid, 0.03 * f_mid);
  std::printf("extra resonance 90 Hz on the carriage: modes %.2f and %.2f Hz (model %.2f, %.2f)\n",
              got_low, got_mid, f_low, f_mid);
}

TEST(Axis2, EncoderInterpolationErrorHasItsPeriodAndAmplitude) {
  EncoderParams e;
  e.interp_period_m = 20e-6;
  e.interp_amplitude_m = 0.4e-6;
  e.interp_phase_rad = 1.1;
  e.resolution_m = 0.0;
  Encoder enc(e, 0.1, 1e-5);
  std::vector<double> err, ph, ph2;
  for (int i = 0; i < 4000; ++i) {  // 10 periods
    const double x = 0.1 + i * 0.05e-6;
    err.push_back(enc.reading_of(x) - x);
    ph.push_back(kTwoPi * x / 20e-6);
    ph2.push_back(kTwoPi * x / 40e-6);
  }
  EXPECT_NEAR(amplitude_at(err, ph), 0.4e-6, 0.004e-6);
  EXPECT_LT(amplitude_at(err, ph2), 0.02e-6);
  // Quantisation: readings are multiples of the resolution.
  e.resolution_m = 0.488e-6;
  Encoder q(e, 0.1, 1e-5);
  q.push(0.001, 0.1 + 3.3e-6);
  const double r = q.quantised_m(0.001) / 0.488e-6;
  EXPECT_NEAR(r, std::round(r), 1e-6);
}

TEST(Axis2, TransportDelayIsTheLagOfTheMeasurement) {
  Axis2Params p = quiet_params();
  p.encoder.delay_s = 1.3e-3;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  const double speed = 0.02;
  std::vector<double> truth_t, truth_x;
  double lag_sum = 0.0;
  int lag_n = 0;
  for (int i = 1; i <= 3000; ++i) {  // 0.3 s
    const double t = i * 1e-4;
    axis.advance(p.start_m + speed * t, 1e-4);
    if (t > 0.2) {
      // The measurement equals the true position delay_s earlier: at constant speed the gap is
      // speed x delay.
      lag_sum += (axis.carriage_m() - (axis.measured_m())) / axis.carriage_velocity_m_s();
      ++lag_n;
    }
  }
  EXPECT_NEAR(lag_sum / lag_n, 1.3e-3, 0.02e-3);
}

TEST(Axis2, TheDelayLineReachesTheLongestDelayWhateverTheStep) {
  // Steps a tenth of the step rule's: the line still holds 2 ms (max_delay_s 2.5 ms).
  Axis2Params p = quiet_params();
  p.encoder.delay_s = 2e-3;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  const double dt = axis.max_step_s() / 10.0;
  const double speed = 0.02;
  double t = 0.0;
  while (t < 0.25) {
    t += dt;
    axis.step(p.start_m + speed * t, dt);
  }
  const double lag_s = (axis.carriage_m() - axis.measured_m()) / axis.carriage_velocity_m_s();
  EXPECT_NEAR(lag_s, 2e-3, 0.03e-3);
}

TEST(Axis2, BacklashIsLostMotionOfItsWidthOnReversal) {
  // Coulomb friction loads the belt at constant speed, so the teeth drive from one side of the
  // dead band going forward and from the other going back: the carriage's lag behind the rotor
  // changes by the width plus twice the stretch F_c (1 / k_belt + 1 / k_tooth).
  Axis2Params p = quiet_params();
  p.belt.backlash_m = 80e-6;
  p.carriage.coulomb_n = 1.0;
  p.carriage.static_n = 1.0;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  const double speed = 5e-3;
  // Carriage minus rotor in the middle of a 1 mm move at constant speed.
  auto lag_during = [&axis, speed](double from, double to) {
    const double dt = 1e-4;
    const int n = static_cast<int>(std::fabs(to - from) / speed / dt);
    double mid = 0.0;
    for (int i = 1; i <= n; ++i) {
      axis.advance(from + (to - from) * i / n, dt);
      if (i == n / 2) mid = axis.carriage_m() - axis.rotor_position_m();
    }
    return mid;
  };
  const double x0 = p.start_m;
  const double forward = lag_during(x0, x0 + 1e-3);
  const double back = lag_during(x0 + 1e-3, x0);
  const double stretch =
      1.0 / Axis2::belt_stiffness_n_m(p.belt, x0 + 0.5e-3) + 1.0 / p.belt.tooth_stiffness_n_m;
  EXPECT_NEAR(back - forward, 80e-6 + 2.0 * 1.0 * stretch, 3e-6);
  std::printf("backlash 80 um: lost motion %.1f um (incl. %.1f um of belt and tooth stretch)\n",
              (back - forward) * 1e6, 2e6 * stretch);
}

TEST(Axis2, DirectionDependentStiffnessIsTheRatioOfTheBeltsStretch) {
  // Coulomb friction F stretches the belt by F / K while the pulley pulls: K(pulling +) going
  // forward, K(pulling -) going back; their ratio is the drawn ratio.
  Axis2Params p = quiet_params();
  p.belt.stiffness_ratio = 1.7;
  p.carriage.coulomb_n = 2.0;
  p.carriage.static_n = 2.0;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  auto stretch_during = [&axis](double from, double to) {
    const double dt = 1e-4;
    const int n = static_cast<int>(std::fabs(to - from) / 5e-3 / dt);
    double mid = 0.0;
    for (int i = 1; i <= n; ++i) {
      axis.advance(from + (to - from) * i / n, dt);
      if (i == n / 2) mid = axis.rotor_position_m() - axis.carriage_m();
    }
    return mid;
  };
  const double x0 = p.start_m;
  const double forward = stretch_during(x0, x0 + 1e-3);
  const double back = stretch_during(x0 + 1e-3, x0);
  const double k = Axis2::belt_stiffness_n_m(p.belt, x0 + 0.5e-3);
  EXPECT_NEAR(forward, 2.0 / (k * std::sqrt(1.7)), 0.03 * forward);
  EXPECT_NEAR(-back / forward, 1.7, 0.05);
}

TEST(Axis2, AtRestNothingDrifts) {
  Axis2Params p;  // defaults: friction and detent on
  p.stepper.detent_torque_nm = 0.01;
  p.stepper.microstep_err4_rad = 0.01;
  p.carriage.extra_mass_kg = 0.1;
  p.belt.stiffness_ratio = 1.6;
  p.encoder.delay_s = 1e-3;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  const double x0 = axis.carriage_m();
  for (int i = 0; i < 5000; ++i) axis.advance(p.start_m, 1e-3);  // 5 s
  EXPECT_NEAR(axis.carriage_m(), x0, 1e-10);
  EXPECT_NEAR(axis.measured_m(), p.start_m, 1e-10);
  EXPECT_LT(axis.kinetic_energy_j(), 1e-15);
  // After a move, settled, it stays.
  for (int i = 1; i <= 200; ++i) axis.advance(p.start_m + 1e-3 * i / 200.0, 1e-3);
  for (int i = 0; i < 1000; ++i) axis.advance(p.start_m + 1e-3, 1e-3);
  const double settled = axis.carriage_m();
  for (int i = 0; i < 5000; ++i) axis.advance(p.start_m + 1e-3, 1e-3);
  EXPECT_NEAR(axis.carriage_m(), settled, 2e-9);
  EXPECT_NEAR(axis.carriage_m(), p.start_m + 1e-3, 10e-6);  // within friction / detent offsets
  EXPECT_LT(axis.kinetic_energy_j(), 1e-12);
}

TEST(Axis2, StepRuleAndSpeed) {
  Axis2Params p;
  auto a = Axis2::create(p);
  ASSERT_TRUE(a.ok()) << a.error().message;
  Axis2& axis = a.value();
  EXPECT_GT(axis.max_step_s(), 0.5e-6);
  EXPECT_LT(axis.max_step_s(), 20e-6);
  const std::clock_t c0 = std::clock();
  const double sim_s = 2.0;
  for (int i = 1; i <= 20000; ++i) {
    const double t = i * 1e-4;
    axis.advance(p.start_m + 0.02 * std::sin(kTwoPi * 2.0 * t), 1e-4);
  }
  const double cpu_s = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  std::printf("step %.2f us, %zu degrees of freedom: %.1f simulated s per CPU s\n",
              axis.max_step_s() * 1e6, axis.degrees_of_freedom(), sim_s / cpu_s);
  EXPECT_GT(sim_s / cpu_s, 1.0);  // at least real time on one core
}

}  // namespace
}  // namespace feedloop::plant2
