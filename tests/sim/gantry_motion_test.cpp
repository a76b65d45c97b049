// Large-signal behaviour of the gantry plant: velocity lag, lost steps (thesis Sect. 5.3-5.4),
// encoder quantisation and noise, determinism, parameter validation.
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "sim/gantry_axis.hpp"
#include "sim/step_driver.hpp"
#include "tests/sim/motion_profile.hpp"

namespace feedloop::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

GantryAxis make(const GantryAxisParams& p) { return std::move(GantryAxis::create(p).value()); }

// Drive a profile with 10 us step updates; call `sample(t)` every sample_dt_s.
template <class F>
void run(GantryAxis& axis, const testing::Profile& prof, double start_mm, double sample_dt_s, F sample) {
  StepDriver drive(axis, axis.mm_per_step(), start_mm);
  const double dt = 1e-5;
  const int per_sample = static_cast<int>(std::lround(sample_dt_s / dt));
  const int n = static_cast<int>(prof.duration_s() / dt);
  for (int k = 1; k <= n; ++k) {
    const double t = k * dt;
    drive.update(t, start_mm + prof.position_mm(t));
    if (k % per_sample == 0) {
      axis.advance_to(t);
      sample(t, drive.commanded_mm());
    }
  }
}

// Steady-state lag at constant velocity v (the nonlinear plant's own balance of forces):
// field behind the command by tau v, rotor behind the field by the sine-law angle that carries
// c2 v, carriage behind the rotor by the belt stretch c2 v / K2 (Eq. 6 in the pulling direction).
double expected_lag_mm(const GantryAxisParams& p, double v_mm_s, double x2_mm) {
  const double v = v_mm_s * 1e-3;
  const double lambda = 2.0 * kPi * p.pulley_radius_mm * 1e-3 * 4.0 / p.full_steps_per_rev;
  const double f_hold = p.motor_stiffness_n_m * lambda / (2.0 * kPi);
  const double frac = 1.0 / std::sqrt(1.0 + std::pow(v_mm_s / p.pullout_corner_speed_mm_s, 2));
  const double force = p.bearing_damping_n_s_m * v;
  const double k2 = p.belt_stiffness_n_m * p.belt_span_mm / (p.belt_span_mm - (p.belt_x0_mm + x2_mm));
  const double lag_m = p.motor_damping_n_s_m / p.motor_stiffness_n_m * v +
                       lambda / (2.0 * kPi) * std::asin(force / (frac * f_hold)) + force / k2;
  return lag_m * 1e3;
}

TEST(GantryMotion, ConstantVelocityTracksWithExpectedLag) {
  for (const auto& [params, name] : {std::pair{thesis_x_axis(), "X"}, std::pair{thesis_y_axis(), "Y"}}) {
    GantryAxisParams p = params;
    p.encoder.noise_um = 0.0;
    GantryAxis axis = make(p);
    const double v = 50.0, a = 2000.0;
    testing::Profile prof;
    prof.add(0.0, a, v / a).add(v, 0.0, 0.4);
    std::vector<double> lags, pos;
    run(axis, prof, 0.0, 1e-3, [&](double t, double) {
      if (t > 0.2) {  // transient over (slowest pole of G_Y: 34 rad/s decay -> 0.15 s to 1 %)
        lags.push_back(prof.position_mm(t) - axis.carriage_mm());
        pos.push_back(axis.carriage_mm());
      }
    });
    double worst = 0.0;
    for (size_t i = 0; i < lags.size(); ++i) {
      worst = std::max(worst, std::abs(lags[i] - expected_lag_mm(p, v, pos[i])));
    }
    // Linear model (Eq. 16): ramp error v * psi1 / psi0 = v (c1/k1 + c2/k2 + c2/k1).
    const double linear_lag = v * (p.motor_damping_n_s_m / p.motor_stiffness_n_m +
                                   p.bearing_damping_n_s_m / p.belt_stiffness_n_m +
                                   p.bearing_damping_n_s_m / p.motor_stiffness_n_m);
    std::printf("%s at %.0f mm/s: lag %.4f mm at x=%.1f, expected %.4f, linear model %.4f; worst |diff| %.2f um\n",
                name, v, lags.back(), pos.back(), expected_lag_mm(p, v, pos.back()), linear_lag, worst * 1e3);
    EXPECT_LT(worst, 0.002) << name;  // 2 um of a ~0.3 mm lag (step quantisation: 10.6 um / 2)
    // The linear model (K2 = k2 everywhere) differs by the belt stiffening with x (Eq. 6): < 5 %.
    EXPECT_NEAR(lags.back(), linear_lag, 0.05 * linear_lag) << name;
    EXPECT_EQ(axis.slip_events(), 0) << name;
  }
}

struct LossCase {
  double accel_mm_s2;
  double speed_change_mm_s;
  bool expect_loss;
};

// Thesis Sect. 5.3-5.4 driven open loop at 150 mm/s on the Y axis (1.07 kg, quarter current):
// no lost steps at 1000-3000 mm/s^2 with the default 15 mm/s speed change, lost steps at
// 6000 mm/s^2 and with a 300 mm/s speed change.
TEST(GantryMotion, LosesStepsInTheThesisHighAccelerationCases) {
  for (const LossCase c : {LossCase{1000, 15, false}, LossCase{3000, 15, false}, LossCase{6000, 15, true},
                           LossCase{3000, 300, true}, LossCase{6000, 300, true}}) {
    GantryAxisParams p = thesis_y_axis();
    p.initial_pos_mm = 50.0;
    GantryAxis axis = make(p);
    const testing::Profile prof = testing::corner_reversal(150.0, c.accel_mm_s2, c.speed_change_mm_s, 0.1);
    double cmd_end = 0.0;
    run(axis, prof, 50.0, 1e-3, [&](double, double cmd) { cmd_end = cmd; });
    axis.advance_to(prof.duration_s() + 0.3);
    const double err_mm = axis.carriage_mm() - cmd_end;
    const double full_step_mm = axis.mm_per_step() * p.microsteps;
    std::printf("a=%5.0f dv=%4.0f: slips %lld, net lost %lld full steps, final error %.4f mm\n", c.accel_mm_s2,
                c.speed_change_mm_s, static_cast<long long>(axis.slip_events()),
                static_cast<long long>(axis.lost_full_steps()), err_mm);
    if (c.expect_loss) {
      EXPECT_GT(axis.slip_events(), 0) << c.accel_mm_s2 << " " << c.speed_change_mm_s;
    } else {
      EXPECT_EQ(axis.slip_events(), 0) << c.accel_mm_s2 << " " << c.speed_change_mm_s;
      EXPECT_LT(std::abs(err_mm), 0.005);
    }
    // The truth counter and the position agree: each lost full step shifts the carriage by one.
    EXPECT_NEAR(err_mm, -static_cast<double>(axis.lost_full_steps()) * full_step_mm, 0.005);
  }
}

TEST(GantryMotion, EncoderQuantisationIs049um) {
  GantryAxisParams p = thesis_x_axis();
  p.encoder.noise_um = 0.0;
  GantryAxis axis = make(p);
  EXPECT_DOUBLE_EQ(axis.encoder_mm_per_count(), 0.49e-3);
  StepDriver drive(axis, axis.mm_per_step());
  for (int i = 1; i <= 2000; ++i) {  // 2000 steps at 20 kHz, then settle
    drive.update(i * 5e-5, 0.7 * i / 2000.0 * 1.0);
  }
  std::vector<double> errs;
  for (double t = 0.3; t < 0.31; t += 1e-3) {
    const int64_t c = axis.read_encoder_counts(t);
    const double truth_um = axis.carriage_mm() * 1e3;
    EXPECT_EQ(c, std::llround(truth_um / 0.49));
    errs.push_back(c * 0.49 - truth_um);
  }
  for (double e : errs) EXPECT_LE(std::abs(e), 0.245 + 1e-9);
}

// MotorPort::set_step_fraction: the driver's current vector moved by a fraction of a microstep
// moves the carriage at rest by that fraction of the step (the device loop's sub-step trim).
TEST(GantryMotion, AStepFractionMovesTheCarriageAtRestByThatFraction) {
  GantryAxisParams p = thesis_x_axis();
  p.encoder.noise_um = 0.0;
  GantryAxis axis = make(p);
  axis.advance_to(0.2);
  const double x0 = axis.carriage_mm();
  const double step_um = axis.mm_per_step() * 1e3;
  for (double f : {0.25, 0.5, -0.5, 1.0}) {
    axis.set_step_fraction(axis.time_s(), static_cast<float>(f));
    axis.advance_to(axis.time_s() + 0.3);
    const double moved_um = (axis.carriage_mm() - x0) * 1e3;
    std::printf("fraction %+.2f: carriage moved %+.3f um (step %.3f um)\n", f, moved_um, step_um);
    EXPECT_NEAR(moved_um, f * step_um, 0.02 * step_um) << f;
  }
}

TEST(GantryMotion, EncoderNoiseHasConfiguredSpread) {
  GantryAxisParams p = thesis_x_axis();
  p.encoder.noise_um = 1.0;
  GantryAxis axis = make(p);
  double sum = 0.0, sum2 = 0.0;
  const int n = 20000;
  for (int i = 1; i <= n; ++i) {
    const double um = axis.read_encoder_counts(i * 1e-5) * 0.49;
    sum += um;
    sum2 += um * um;
  }
  const double sd = std::sqrt(sum2 / n - (sum / n) * (sum / n));
  const double expected = std::sqrt(1.0 + 0.49 * 0.49 / 12.0);  // noise and quantisation
  std::printf("encoder noise: sd %.3f um (expected %.3f)\n", sd, expected);
  EXPECT_NEAR(sd, expected, 0.05 * expected);
  EXPECT_NEAR(sum / n, 0.0, 0.05);
}

std::vector<int64_t> trace(uint64_t seed) {
  GantryAxisParams p = thesis_y_axis();
  p.seed = seed;
  p.effects.coulomb_friction = {true, 1.5};
  GantryAxis axis = make(p);
  std::vector<int64_t> out;
  StepDriver drive(axis, axis.mm_per_step());
  const testing::Profile prof = testing::corner_reversal(100.0, 3000.0, 15.0, 0.02);
  for (int k = 1; k * 1e-4 < prof.duration_s(); ++k) {
    drive.update(k * 1e-4, prof.position_mm(k * 1e-4));
    if (k % 10 == 0) out.push_back(axis.read_encoder_counts(k * 1e-4));
  }
  return out;
}

TEST(GantryMotion, DeterministicForASeed) {
  const std::vector<int64_t> a = trace(7), b = trace(7), c = trace(8);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a, b);
  size_t differ = 0;
  for (size_t i = 0; i < a.size(); ++i) differ += a[i] != c[i];
  EXPECT_GT(differ, a.size() / 4);  // the noise differs, the motion does not
}

TEST(GantryMotion, RejectsBadParametersWithAMessage) {
  GantryAxisParams p = thesis_x_axis();
  p.microsteps = 0;
  auto r = GantryAxis::create(p);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("microsteps"), std::string::npos);
  p = thesis_x_axis();
  p.effects.scale_error = {true, -1.0};
  r = GantryAxis::create(p);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("scale"), std::string::npos);
  p = thesis_x_axis();
  p.encoder.resolution_um = 0.0;
  EXPECT_FALSE(GantryAxis::create(p).ok());
}

TEST(GantryMotion, DisabledMotorHoldsNoTorque) {
  GantryAxisParams p = thesis_x_axis();
  GantryAxis axis = make(p);
  axis.set_enabled(0.0, false);
  StepDriver drive(axis, axis.mm_per_step());
  for (int i = 1; i <= 100; ++i) drive.update(i * 1e-3, 0.01 * i);  // 1 mm commanded
  axis.advance_to(0.2);
  EXPECT_LT(std::abs(axis.carriage_mm()), 1e-6);
  axis.set_enabled(0.2, true);  // the field pulls the rotor to the nearest equilibrium
  axis.advance_to(0.6);
  const double full_step_mm = axis.mm_per_step() * p.microsteps;
  EXPECT_NEAR(axis.carriage_mm(), 1.0 - static_cast<double>(axis.lost_full_steps()) * full_step_mm, 0.01);
}

}  // namespace
}  // namespace feedloop::sim

#include "sim/cartesian_plant.hpp"

namespace feedloop::sim {
namespace {

TEST(CartesianPlant, ThreeIndependentAxesWithTheirOwnNoise) {
  auto plant = CartesianPlant::create(CartesianPlantParams{});
  ASSERT_TRUE(plant.ok());
  StepDriver x(plant->port(0), plant->axis(0).mm_per_step());
  for (int k = 1; k <= 1000; ++k) x.update(k * 1e-4, 0.5 * k / 1000.0);
  plant->advance_to(0.5);
  EXPECT_NEAR(plant->axis(0).carriage_mm(), x.commanded_mm(), 1e-4);
  EXPECT_EQ(plant->axis(1).carriage_mm(), 0.0);
  int differ = 0;
  for (int k = 1; k <= 200; ++k) {  // Y and Z at rest: noise only, different per axis
    const double t = 0.5 + k * 1e-3;
    differ += plant->port(1).read_encoder_counts(t) != plant->port(2).read_encoder_counts(t);
  }
  EXPECT_GT(differ, 50);
  CartesianPlantParams bad;
  bad.axes[2].microsteps = 0;
  auto r = CartesianPlant::create(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("axis z"), std::string::npos);
}

}  // namespace
}  // namespace feedloop::sim
