// Real-time checks of the model-based feedforward: step() and reset() allocate nothing (malloc is
// counted by interposing it; skipped under sanitizers, which own malloc), and the cost of one
// servo period is measured and printed (gantry: 2 SISO inverses of 5 states; delta: one 3x3
// inverse of 21 states blended from 8 grid points), with the budget of DESIGN.md's servo loop.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "control/feedforward/delta_lpv.hpp"
#include "control/feedforward/gantry_lpv.hpp"
#include "control/feedforward/velocity_jump_smoother.hpp"
#include "model/delta_kinematics.hpp"

#include "tests/common/malloc_counter.hpp"

namespace feedloop::control {
namespace {

// As the factory builds it: behind the velocity-jump smoother (engine/control_config.hpp).
std::unique_ptr<Feedforward> with_jump_smoothing(std::unique_ptr<Feedforward> inner) {
  VelocityJumpSmoothing p;
  p.max_half_width = 15;
  auto s = VelocityJumpSmoother::create(std::move(inner), p);
  EXPECT_TRUE(s.ok());
  return std::move(s.value());
}

std::unique_ptr<Feedforward> gantry(bool carriage_mode = false) {
  std::array<GantryAxisLpvModel, 2> axes;
  axes[0].params = model::thesis_x_axis();
  axes[1].params = model::thesis_y_axis();
  for (auto& a : axes) {
    a.belt_unit_stiffness_n = a.params.k2_n_m * 0.3;
    a.pulley_distance_mm = 300.0;
    a.coulomb_friction_n = 2.0;  // the Dahl friction term runs too
    if (carriage_mode) a.carriage_mode = {55.0, 0.05, 0.12};  // six-state designs
  }
  LpvDesignOptions opt;
  auto ff = GantryLpvFeedforward::create(axes, opt);
  EXPECT_TRUE(ff.ok());
  return with_jump_smoothing(std::move(ff.value()));
}

std::unique_ptr<Feedforward> delta() {
  DeltaLpvGrid g;
  g.z_min_mm = 20.0;
  g.z_max_mm = 40.0;
  g.z_step_mm = 20.0;
  LpvDesignOptions opt;
  auto ff = DeltaLpvFeedforward::create(model::delta_table1_params(), model::ForceTransform::Paper, g, opt, 9.81);
  EXPECT_TRUE(ff.ok());
  return with_jump_smoothing(std::move(ff.value()));
}

// A circle of radius 40 mm at 100 mm/s around the centre, z = 30 mm: crosses many grid cells.
FeedforwardInput circle(int k, bool is_delta) {
  const double t = k * 1e-3, w = 100.0 / 40.0;
  const Eigen::Vector3d X(40.0 * std::cos(w * t), 40.0 * std::sin(w * t), 30.0);
  FeedforwardInput in;
  in.nozzle_mm = {X.x(), X.y(), X.z()};
  if (is_delta) {
    const Eigen::Vector3d q = model::inverse_kinematics(model::delta_table1_params().geometry, X).value();
    in.r_mm = {q.x(), q.y(), q.z(), 0.01 * k};
  } else {
    in.r_mm = {X.x(), X.y(), X.z(), 0.01 * k};
  }
  return in;
}

void check_no_allocation(Feedforward& ff, bool is_delta) {
#ifndef FEEDLOOP_COUNT_MALLOC
  (void)ff;
  (void)is_delta;
  GTEST_SKIP() << "malloc counting is off under sanitizers / non-glibc";
#else
  std::vector<FeedforwardInput> plan;
  for (int k = 0; k < 2000; ++k) plan.push_back(circle(k, is_delta));
  g_mallocs = 0;
  g_counting = true;
  { Eigen::VectorXd v(100); v.setZero(); }  // the counter works
  g_counting = false;
  ASSERT_GT(g_mallocs.load(), 0);
  g_mallocs = 0;
  JointArray u{};
  double sum = 0;
  g_counting = true;
  ff.reset(plan[0]);
  for (const FeedforwardInput& in : plan) {
    ff.step(in, u);
    sum += u[0];
  }
  ff.reset(plan[100]);
  g_counting = false;
  EXPECT_EQ(g_mallocs.load(), 0);
  EXPECT_TRUE(std::isfinite(sum));
#endif
}

double cost_us(Feedforward& ff, bool is_delta) {
  constexpr int kN = 4000;
  std::vector<FeedforwardInput> plan;
  for (int k = 0; k < kN; ++k) plan.push_back(circle(k, is_delta));
  ff.reset(plan[0]);
  JointArray u{};
  double sum = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (const FeedforwardInput& in : plan) {
    ff.step(in, u);
    sum += u[0];
  }
  const auto t1 = std::chrono::steady_clock::now();
  EXPECT_TRUE(std::isfinite(sum));
  return std::chrono::duration<double, std::micro>(t1 - t0).count() / kN;
}

TEST(FeedforwardRt, GantryStepDoesNotAllocate) {
  auto ff = gantry();
  check_no_allocation(*ff, false);
  auto with_mode = gantry(true);  // the extra resonance in every design
  check_no_allocation(*with_mode, false);
}

TEST(FeedforwardRt, DeltaStepDoesNotAllocate) {
  auto ff = delta();
  check_no_allocation(*ff, true);
}

TEST(FeedforwardRt, CostPerServoPeriod) {
  auto g = gantry();
  auto d = delta();
  const double g_us = cost_us(*g, false), d_us = cost_us(*d, true);
  std::printf("feedforward step(): gantry %.2f us, delta %.2f us per servo period (P = %d)\n", g_us, d_us,
              d->preview_samples());
#if defined(FEEDLOOP_SANITIZED) || !defined(NDEBUG)
  GTEST_SKIP() << "timing budget checked in optimised builds only";
#else
  EXPECT_LT(g_us, 50.0);  // "well under 50 us": the budget per servo period
  EXPECT_LT(d_us, 50.0);
#endif
}

}  // namespace
}  // namespace feedloop::control
