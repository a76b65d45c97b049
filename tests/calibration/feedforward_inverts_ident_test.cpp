// The identification's model and the LPV feedforward are two codes of one model (issue 15 item
// 4: "every named effect flows back into the model the feedforward uses"): the identified axis
// (ident::simulate_axis) driven by the feedforward's command for that same model must carry the
// carriage on the planned path. Through reversals at 100 mm/s and 3000 mm/s^2 with the model a
// calibration of the second simulator's friction draw 1 (X) carried: Eq. 13 with the field lag
// on the load angle, Dahl friction, a direction ratio.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

#include "control/feedforward/gantry_lpv.hpp"
#include "ident/axis_model.hpp"

namespace feedloop {
namespace {

constexpr double kPeriodS = 1e-3;
constexpr int kPreview = 20;

// Rest-to-rest trapezoids between 100 and 120 mm and back, three times, sampled every period;
// each move ends on its end point (a = 3000 mm/s^2, v = 100 mm/s: 33 ms ramps, 0.13 s cruise).
std::vector<double> reversals_mm() {
  const double a = 3000.0, v = 100.0, d = 20.0;
  const double t_ramp = v / a, t_cruise = (d - v * t_ramp) / v, t_move = 2.0 * t_ramp + t_cruise;
  auto along = [&](double t) {  // distance covered t after a move's start
    if (t <= t_ramp) return 0.5 * a * t * t;
    if (t <= t_ramp + t_cruise) return 0.5 * a * t_ramp * t_ramp + v * (t - t_ramp);
    const double td = std::min(t, t_move) - t_ramp - t_cruise;
    return d - 0.5 * a * (t_ramp - td) * (t_ramp - td);
  };
  std::vector<double> r(100, 100.0);  // at rest first
  for (int move = 0; move < 6; ++move) {
    const double from = move % 2 == 0 ? 100.0 : 120.0, sign = move % 2 == 0 ? 1.0 : -1.0;
    const int n = static_cast<int>(std::ceil(t_move / kPeriodS));
    for (int k = 1; k <= n; ++k) r.push_back(from + sign * along(k * kPeriodS));
    r.insert(r.end(), 20, r.back());  // 20 ms still at each end
  }
  r.insert(r.end(), 200, r.back());
  return r;
}

// The model of one axis, as identification writes it and as the feedforward takes it (the
// overlay's keys; engine/control_config.cpp maps them the same way).
ident::AxisModel identified(double friction_n, double presliding_um, double ratio,
                            double backlash_um) {
  ident::AxisModel m;
  m.m1_kg = 0.0547;
  m.m2_kg = 0.45;
  m.k1_n_m = 22894.0;
  m.k2_n_m = 652043.0;
  m.c1_n_s_m = 12.25;
  m.c2_n_s_m = 54.17;
  m.field_lag_ms = 0.124;
  m.friction_force_n = friction_n;
  m.presliding_um = presliding_um;
  m.set(ident::Effect::kCoulombFriction, friction_n > 0.0);
  m.stiffness_ratio = ratio;
  m.set(ident::Effect::kDirectionStiffness, ratio != 1.0);
  m.backlash_width_um = backlash_um;
  m.set(ident::Effect::kBacklash, backlash_um > 0.0);
  return m;
}

control::GantryAxisLpvModel feedforward_model(const ident::AxisModel& m) {
  control::GantryAxisLpvModel f;
  f.params.m1_kg = m.m1_kg;
  f.params.m2_kg = m.m2_kg;
  f.params.k1_n_m = m.k1_n_m;
  f.params.k2_n_m = m.k2_n_m;
  f.params.c1_n_s_m = m.c1_n_s_m;
  f.params.c2_n_s_m = m.c2_n_s_m;
  f.belt_unit_stiffness_n = 0.0;  // the calibrated belt: uniform k2
  f.field_lag_s = m.field_lag_ms * 1e-3;
  f.coulomb_friction_n = m.has(ident::Effect::kCoulombFriction) ? m.friction_force_n : 0.0;
  f.friction_bristle_mm = m.presliding_um * 1e-3;
  f.direction_ratio = m.has(ident::Effect::kDirectionStiffness) ? m.stiffness_ratio : 1.0;
  f.backlash_mm = m.has(ident::Effect::kBacklash) ? m.backlash_width_um * 1e-3 : 0.0;
  f.min_mm = 0.0;
  f.max_mm = 250.0;
  return f;
}

struct Miss {
  double rms_um = 0.0, max_um = 0.0;
};

// The identified model driven by the command `ff_model`'s feedforward gives for r: its carriage
// against r after the first 100 ms.
Miss carriage_miss(const ident::AxisModel& plant, const control::GantryAxisLpvModel& ff_model,
                   const std::vector<double>& r) {
  control::LpvDesignOptions opt;
  opt.period_s = kPeriodS;
  opt.preview_samples = kPreview;
  auto ff = control::GantryLpvFeedforward::create({ff_model, ff_model}, opt);
  EXPECT_TRUE(ff.ok());
  if (!ff.ok()) return {1e9, 1e9};
  control::FeedforwardInput at;
  at.r_mm = {r[0], r[0], 0.0, 0.0};
  ff.value()->reset(at);
  std::vector<double> u(r.size());
  control::JointArray out{};
  for (size_t k = 0; k < r.size(); ++k) {
    control::FeedforwardInput in = at;
    in.r_mm[0] = in.r_mm[1] = r[std::min(r.size() - 1, k + kPreview)];  // P periods ahead
    ff.value()->step(in, out);
    u[k] = out[0];  // the command for t_k
  }
  std::vector<double> y;
  EXPECT_TRUE(ident::simulate_axis(plant, u, kPeriodS, &y).ok());
  Miss m;
  size_t n = 0;
  for (size_t k = 100; k < r.size(); ++k) {
    const double e_um = (y[k] - r[k]) * 1e3;
    m.rms_um += e_um * e_um;
    m.max_um = std::max(m.max_um, std::abs(e_um));
    ++n;
  }
  m.rms_um = std::sqrt(m.rms_um / static_cast<double>(n));
  return m;
}

TEST(FeedforwardInvertsIdent, FrictionAndDirectionRatioAreInvertedThroughReversals) {
  const std::vector<double> r = reversals_mm();
  const ident::AxisModel linear = identified(0.0, 4.8, 1.0, 0.0);
  const ident::AxisModel friction = identified(1.49, 4.8, 1.0, 0.0);
  const ident::AxisModel ratio = identified(0.0, 4.8, 1.5, 0.0);
  const Miss lin = carriage_miss(linear, feedforward_model(linear), r);
  const Miss fr = carriage_miss(friction, feedforward_model(friction), r);
  const Miss fr_blind = carriage_miss(friction, feedforward_model(linear), r);  // its term left out
  const Miss ra = carriage_miss(ratio, feedforward_model(ratio), r);
  const Miss ra_blind = carriage_miss(ratio, feedforward_model(linear), r);
  const ident::AxisModel both = identified(1.49, 4.8, 0.67, 0.0);
  const Miss bo = carriage_miss(both, feedforward_model(both), r);
  std::printf(
      "identified model on the feedforward's command, carriage - r (rms / max um): Eq. 13 + "
      "field lag %.2f / %.2f | friction 1.49 N %.2f / %.2f (without its term %.1f / %.1f) | "
      "ratio 1.5 %.2f / %.2f (without its term %.2f / %.2f) | friction and ratio 0.67 %.2f / "
      "%.2f\n",
      lin.rms_um, lin.max_um, fr.rms_um, fr.max_um, fr_blind.rms_um, fr_blind.max_um, ra.rms_um,
      ra.max_um, ra_blind.rms_um, ra_blind.max_um, bo.rms_um, bo.max_um);
  EXPECT_LT(lin.rms_um, 1.0);
  EXPECT_LT(lin.max_um, 2.0);
  // The friction's term: within 2.5 um rms of a 68 um rms effect. What is left is a creep of a
  // few um while the carriage stands after a move, the command constant: the Dahl force held over
  // each substep (1.38 / 3.50 um with 40 substeps instead of 5).
  EXPECT_LT(fr.rms_um, 2.5);
  EXPECT_LT(fr.max_um, 6.0);
  EXPECT_GT(fr_blind.rms_um, 20.0 * fr.rms_um);
  EXPECT_LT(ra.rms_um, 1.0);
  EXPECT_LT(ra.max_um, 2.0);
  EXPECT_GT(ra_blind.rms_um, 2.0 * ra.rms_um);
  // Both: the model's belt is simulated in the regime each substep begins in
  // (ident/axis_model.cpp). When the ratio's stiffness was a held force instead, this case missed
  // by 13.5 / 49 um.
  EXPECT_LT(bo.rms_um, 2.5);
  EXPECT_LT(bo.max_um, 6.0);
}

// Backlash is inverted approximately: the command crosses the dead band on the planned belt
// force, (w / 2) tanh(F / F0), where the model's belt goes slack at once. The miss is bounded
// and a fraction of what the dead band costs without its term. (The model's own crossing is
// placed within an eighth of a substep: with 1000 substeps the figures are the same to 1 %.)
TEST(FeedforwardInvertsIdent, BacklashIsCrossedWithinAFractionOfItsWidth) {
  const std::vector<double> r = reversals_mm();
  const ident::AxisModel with = identified(0.0, 4.8, 1.0, 80.0);
  const ident::AxisModel without = identified(0.0, 4.8, 1.0, 0.0);
  const Miss full = carriage_miss(with, feedforward_model(with), r);
  const Miss blind = carriage_miss(with, feedforward_model(without), r);
  std::printf(
      "backlash 80 um: feedforward with it rms %.2f max %.2f um, without it rms %.1f max %.1f um\n",
      full.rms_um, full.max_um, blind.rms_um, blind.max_um);
  EXPECT_LT(full.max_um, 0.35 * 80.0);
  EXPECT_LT(full.rms_um, 0.3 * blind.rms_um);
}

}  // namespace
}  // namespace feedloop
