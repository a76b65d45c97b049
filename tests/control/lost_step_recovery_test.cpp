// Sim-in-the-loop: the thesis's Sect. 5.4 case that loses steps (Y axis, 150 mm/s with a 300 mm/s
// speed change: an instant reversal) on the nonlinear stepper + belt simulator. Open loop the
// carriage ends off by the lost full steps; with F = 1 + PI + LostStepDetector (expected
// deflection from the linear model, Eq. 15) every slip is detected with the simulator's own
// count, recovered through PiController::shift, and the carriage ends on target.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>

#include "control/lost_step_detector.hpp"
#include "control/pi_controller.hpp"
#include "model/discrete.hpp"
#include "model/gantry_axis.hpp"
#include "sim/gantry_axis.hpp"
#include "sim/step_driver.hpp"
#include "tests/sim/motion_profile.hpp"

namespace fc = feedloop::control;
namespace fs = feedloop::sim;

namespace {

constexpr double kPeriodS = 1e-3;
constexpr double kStartMm = 50.0;
constexpr int kSubsteps = 100;  // step-driver updates per servo period (10 us)

struct Outcome {
  double final_error_mm = 0.0;      // carriage - reference at the end, after settling
  std::int64_t sim_slips = 0;       // the simulator's slip events
  double sim_lost_mm = 0.0;         // net lost full steps x full-step length
  std::int64_t events = 0;          // detector events
  double detected_mm = 0.0;         // their sum
};

// recovery_mm_s: the slip is handed to PiController::shift at this rate (infinity: at once).
Outcome run(bool closed_loop, double recovery_mm_s) {
  fs::GantryAxisParams p = fs::thesis_y_axis();
  p.initial_pos_mm = kStartMm;
  fs::GantryAxis axis = std::move(fs::GantryAxis::create(p).value());
  fs::StepDriver drive(axis, axis.mm_per_step(), kStartMm);
  const double full_step_mm = axis.mm_per_step() * p.microsteps;

  fc::PiController pi;
  EXPECT_TRUE(pi.configure(fc::PiParams{0.5, 20.0, kPeriodS, 50.0, 5.0, true}).ok());  // thesis gains
  fc::LostStepDetector det;
  fc::LostStepParams lp;
  lp.threshold_mm = 0.3;
  lp.full_step_mm = full_step_mm;
  EXPECT_TRUE(det.configure(lp).ok());
  // The model's motor -> carriage response (thesis Eq. 15, SI) predicts the deflection.
  auto d = feedloop::model::discretize_zoh(
      feedloop::model::gantry_state_space(feedloop::model::thesis_y_axis()), kPeriodS);
  EXPECT_TRUE(d.ok());
  feedloop::model::DiscreteLtiFilter model;
  EXPECT_TRUE(model.configure(*d).ok());

  const auto prof = fs::testing::corner_reversal(150.0, 3000.0, 300.0, 0.1);
  const int periods = static_cast<int>(prof.duration_s() / kPeriodS) + 500;
  auto reference = [&](double t) { return kStartMm + prof.position_mm(std::min(t, prof.duration_s())); };
  Outcome o;
  double cmd_prev = kStartMm;
  double recovery_left_mm = 0.0;
  for (int k = 0; k < periods; ++k) {
    const double t = k * kPeriodS;
    axis.advance_to(t);
    const double enc_mm = kStartMm + static_cast<double>(axis.read_encoder_counts(t)) * axis.encoder_mm_per_count();
    const double motor_mm = drive.commanded_mm();
    double u_mm = 0.0;
    if (closed_loop) {
      const double motor_m = (motor_mm - kStartMm) * 1e-3;
      double predicted_m = 0.0;
      model.step(&motor_m, &predicted_m);
      const double expected_mm = motor_mm - kStartMm - predicted_m * 1e3;
      if (auto ev = det.update(motor_mm, enc_mm, expected_mm)) {
        recovery_left_mm += ev->size_mm;  // recovery: the motor makes up the lost steps
        ++o.events;
        o.detected_mm += ev->size_mm;
      }
      const double step_mm = std::clamp(recovery_left_mm, -recovery_mm_s * kPeriodS, recovery_mm_s * kPeriodS);
      pi.shift(step_mm);
      recovery_left_mm -= step_mm;
      u_mm = pi.update(reference(t) - enc_mm);
    }
    // Motor command for t_{k+1}: F = 1 plus the correction, stepped out evenly over the period.
    const double cmd = reference(t + kPeriodS) + u_mm;
    for (int j = 1; j <= kSubsteps; ++j)
      drive.update(t + kPeriodS * j / kSubsteps, cmd_prev + (cmd - cmd_prev) * j / kSubsteps);
    cmd_prev = cmd;
  }
  axis.advance_to(periods * kPeriodS);
  o.final_error_mm = axis.carriage_mm() - reference(periods * kPeriodS);
  o.sim_slips = axis.slip_events();
  o.sim_lost_mm = static_cast<double>(axis.lost_full_steps()) * full_step_mm;
  return o;
}

}  // namespace

TEST(LostStepRecovery, PiRecoversStepsLostAtAnInstantReversal) {
  const Outcome open = run(false, 0.0);
  std::printf("open loop: %lld slips, lost %.3f mm, final error %.3f mm\n", static_cast<long long>(open.sim_slips),
              open.sim_lost_mm, open.final_error_mm);
  // Open loop: the carriage ends off by exactly the lost steps.
  ASSERT_GT(open.sim_slips, 0);
  EXPECT_GT(std::abs(open.final_error_mm), 0.5);
  EXPECT_NEAR(open.final_error_mm, -open.sim_lost_mm, 0.02);
  for (double recovery_mm_s : {std::numeric_limits<double>::infinity(), 10.0}) {
    const Outcome closed = run(true, recovery_mm_s);
    std::printf("PI + detector, recovery at %.0f mm/s: %lld slips, lost %.3f mm, %lld events detecting %.3f mm, "
                "final error %.4f mm\n",
                recovery_mm_s, static_cast<long long>(closed.sim_slips), closed.sim_lost_mm,
                static_cast<long long>(closed.events), closed.detected_mm, closed.final_error_mm);
    // Closed loop: the slips happen too (more of them: making up steps while the motor runs at its
    // pull-out limit asks for more force than it has), every lost full step is detected and the
    // position recovered.
    ASSERT_GT(closed.sim_slips, 0);
    EXPECT_GT(closed.events, 0);
    EXPECT_NEAR(closed.detected_mm, closed.sim_lost_mm, 1e-9) << recovery_mm_s;
    EXPECT_LT(std::abs(closed.final_error_mm), 0.01) << recovery_mm_s;
  }
}
