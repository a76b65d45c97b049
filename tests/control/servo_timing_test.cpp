// The host loop's control law (engine::ServoControl, control.loop: host) on time-stamped encoder
// samples (issue 13 item 4): a servo cycle 20 ms late neither drops nor doubles the PI's
// correction (the integral advances by the 20 ms between the samples: K_I e dt, thesis Sect. 4.6),
// and the burst of command samples the late cycle emits ramps the correction at the rate the
// clamp allows per command period instead of jumping.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "engine/servo_control.hpp"

namespace feedloop::engine {
namespace {

std::unique_ptr<ServoControl> make_control() {
  ServoControlParams p;
  p.control.mode = config::ControlMode::pi;
  p.control.loop = config::ControlLoop::host;
  p.control.kp = 0.5;
  p.control.ki_per_s = 20.0;
  p.control.max_correction_mm_s = 50.0;
  p.control.max_following_error_mm = 20.0;
  p.period_s = 1e-3;
  p.has_encoder[0] = true;
  p.joint_names[0] = "x";
  p.guard[0].max_following_error_mm = 20.0;
  auto c = ServoControl::create(p, nullptr);
  EXPECT_TRUE(c.ok()) << c.error().message;
  return std::move(c.value());
}

// One servo cycle at t_ms: the sample of that instant (desired r, encoder y), then `commands`
// command samples. Returns the commanded corrections.
struct Loop {
  std::unique_ptr<ServoControl> c = make_control();
  std::vector<double> commanded_mm;
  double r_mm = 10.0, y_mm = 10.0;
  void cycle(double t_ms, int commands) {
    ServoControl::ExecutedSample x;
    x.desired_mm[0] = r_mm;
    x.motor_mm[0] = y_mm;  // the carriage where the motor is: no slip to find
    c->advance_model(x);
    ServoControl::FeedbackInput in;
    in.now_s = t_ms * 1e-3;
    in.print_time_s = in.now_s;
    in.desired_mm[0] = r_mm;
    in.encoder_mm[0] = y_mm;
    in.sample_time_s[0] = in.now_s;
    in.fresh[0] = true;
    ServoEvent ev;
    bool has_event = false;
    ASSERT_TRUE(c->update_feedback(in, &ev, &has_event)) << c->fault_text();
    EXPECT_FALSE(has_event);
    for (int i = 0; i < commands; ++i) {
      control::FeedforwardInput ahead;
      control::JointArray u_ff{}, u{};
      c->command(ahead, u_ff, u);
      commanded_mm.push_back(u[0] - u_ff[0]);
    }
  }
};

TEST(ServoTiming, ALateCycleNeitherDropsNorDoublesTheIntegral) {
  Loop on_time, late;
  on_time.y_mm = late.y_mm = 9.9;  // a constant 0.1 mm error
  for (int k = 0; k <= 40; ++k) on_time.cycle(k, 1);
  for (int k = 0; k <= 10; ++k) late.cycle(k, 1);
  late.cycle(30, 20);  // woke 19 ms late: one sample 20 ms after the last, 20 commands at once
  for (int k = 31; k <= 40; ++k) late.cycle(k, 1);
  // u = K_P e + K_I e t: 0.05 + 20 x 0.1 x 40 ms (the first update, 0.052 mm from 0, hits the
  // 0.05 mm clamp and conditional integration holds its integral back).
  EXPECT_NEAR(on_time.c->correction_mm()[0], 0.05 + 20.0 * 0.1 * 0.040, 1e-9);
  EXPECT_NEAR(late.c->correction_mm()[0], on_time.c->correction_mm()[0], 1e-12);
  // Counting cycles instead (dt = 1 ms per update) the late run would be 19 ms of integral short:
  // 0.038 mm, 29 % of this correction.
  ASSERT_EQ(late.commanded_mm.size(), on_time.commanded_mm.size());
  EXPECT_NEAR(late.commanded_mm.back(), on_time.commanded_mm.back(), 1e-12);
}

TEST(ServoTiming, TheBurstAfterALateCycleRampsTheCorrection) {
  Loop on_time, late;
  on_time.y_mm = late.y_mm =
      5.0;  // 5 mm of error: the PI wants 2.5 mm at once, the clamp allows 0.05 mm/ms
  for (int k = 0; k <= 40; ++k) on_time.cycle(k, 1);
  for (int k = 0; k <= 10; ++k) late.cycle(k, 1);
  late.cycle(30, 20);
  for (int k = 31; k <= 40; ++k) late.cycle(k, 1);
  // The PI's output moved 20 x 0.05 mm over the 20 ms between the samples, as on time.
  EXPECT_NEAR(late.c->correction_mm()[0], on_time.c->correction_mm()[0], 1e-12);
  EXPECT_NEAR(on_time.c->correction_mm()[0], 41 * 0.05, 1e-9);
  // In the commands no step exceeds the clamp and the recovery's rate per period, (50 + 10) mm/s
  // x 1 ms; the burst reaches the PI's output within its 20 samples.
  double largest_step_mm = 0.0;
  for (size_t i = 1; i < late.commanded_mm.size(); ++i)
    largest_step_mm =
        std::max(largest_step_mm, std::fabs(late.commanded_mm[i] - late.commanded_mm[i - 1]));
  EXPECT_LE(largest_step_mm, 0.06 + 1e-12);
  EXPECT_GT(largest_step_mm, 0.05);  // the ramp did work: the burst moved faster than on time
  EXPECT_NEAR(late.commanded_mm[10 + 20], late.c->correction_mm()[0] - 10 * 0.05, 1e-9);
  EXPECT_NEAR(late.commanded_mm.back(), on_time.commanded_mm.back(), 1e-9);
}

}  // namespace
}  // namespace feedloop::engine
