// The control primitives' per-period calls allocate nothing: PiController::update/shift,
// InputShaper::step/reset (cartesian and joint space), LostStepDetector::update including an
// event, EncoderGuard::update including a trip and its message. malloc is counted by interposing
// it (tests/common/malloc_counter.hpp); skipped under sanitizers, which own malloc.
#include <gtest/gtest.h>

#include <cmath>

#include "control/encoder_guard.hpp"
#include "control/input_shaper.hpp"
#include "control/lost_step_detector.hpp"
#include "control/pi_controller.hpp"
#include "engine/control_config.hpp"
#include "planner/kinematics.hpp"

#include "tests/common/malloc_counter.hpp"

namespace fc = feedloop::control;

TEST(ControlPrimitivesRt, PerPeriodCallsDoNotAllocate) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting is off under sanitizers / non-glibc";
#else
  g_counting = true;
  { std::string s(1000, 'x'); EXPECT_EQ(s.size(), 1000u); }  // sanity: the counter sees this
  g_counting = false;
  ASSERT_GT(g_mallocs.load(), 0);
  g_mallocs = 0;

  fc::PiController pi;
  ASSERT_TRUE(pi.configure(fc::PiParams{}).ok());
  feedloop::planner::PlannerConfig pc;
  pc.kinematics = feedloop::planner::KinematicsKind::corexy;
  auto corexy = feedloop::planner::make_kinematics(pc);
  pc.kinematics = feedloop::planner::KinematicsKind::delta;
  auto delta = feedloop::planner::make_kinematics(pc);
  feedloop::config::ShaperConfig sc;
  sc.type = feedloop::config::ShaperType::ei;
  auto setup_xy = feedloop::engine::input_shaper_setup(sc, *corexy, 1e-3);
  auto setup_delta = feedloop::engine::input_shaper_setup(sc, *delta, 1e-3);
  ASSERT_TRUE(setup_xy.ok() && setup_delta.ok());
  fc::InputShaper shaper_xy, shaper_delta;
  ASSERT_TRUE(shaper_xy.configure(*setup_xy).ok());
  ASSERT_TRUE(shaper_delta.configure(*setup_delta).ok());
  fc::LostStepDetector det;
  fc::LostStepParams lp;
  lp.full_step_mm = 0.2;
  ASSERT_TRUE(det.configure(lp).ok());
  fc::EncoderGuard guard;
  ASSERT_TRUE(guard.configure(fc::EncoderGuardParams{}).ok());

  double sum = 0.0;
  int events = 0;
  fc::FeedforwardInput in;
  fc::JointArray u{};
  g_counting = true;
  shaper_xy.reset(in);
  shaper_delta.reset(in);
  for (int k = 0; k < 5000; ++k) {
    const double t = k * 1e-3;
    in.nozzle_mm = {50.0 * std::sin(t), 30.0 * std::cos(t), 0.2};
    in.r_mm = {in.nozzle_mm[0] + in.nozzle_mm[1], in.nozzle_mm[0] - in.nozzle_mm[1], 0.2, t};
    shaper_xy.step(in, u);
    sum += u[0];
    shaper_delta.step(in, u);
    sum += u[1];
    sum += pi.update(0.01 * std::sin(k * 0.01));
    if (k == 2500) pi.shift(0.8);
    const double slip = k >= 3000 ? 0.8 : 0.0;
    if (auto ev = det.update(t, t - slip)) events += static_cast<int>(ev->count);
    // Trips at k = 4002: 5 mm + 3 ms of motion, the third implausible sample in a row.
    guard.update({true, t + (k >= 4000 ? 5.0 : 0.0), t, t, t});
  }
  g_counting = false;
  EXPECT_EQ(g_mallocs.load(), 0);
  EXPECT_TRUE(std::isfinite(sum));
  EXPECT_EQ(events, 1);
  EXPECT_EQ(guard.fault(), fc::EncoderFault::jump);
  EXPECT_STREQ(guard.message(), "x: encoder jump of 5.003 mm in 3.0 ms (limit 1.850 mm; 3 samples in a row)");
#endif
}
