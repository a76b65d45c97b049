// The calibration program (ident/excitation.hpp) and what it adds to identification (issue 15):
// its sections, and a resonance above the heavy Y axis's belt mode that random moves leave below
// the time-domain test but the held-out FRF shows.
#include <gtest/gtest.h>

#include <numbers>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "ident/excitation.hpp"
#include "ident/fit.hpp"
#include "ident/report.hpp"
#include "plant2/axis2.hpp"
#include "plant2/draw.hpp"
#include "plant2/recording.hpp"
#include "sim/experiments/gantry_recording.hpp"

namespace feedloop::ident {
namespace {

TEST(CalibrationProgram, CyclesOfFourSectionsJoinedWithoutJumps) {
  CalibrationProgramOptions o;
  const std::vector<double> u = calibration_program(o);
  // One cycle: 6 s random, 6 s sweep, reversals of 1 mm at 2, 5 and 12 mm/s (two periods each),
  // one 20 mm run at 10 mm/s each way.
  const double reversals_s = 2.0 * (2.0 / 2.0 + 2.0 / 5.0 + 2.0 / 12.0);
  const double cycle_s = 6.0 + 6.0 + reversals_s + 2.0 * 20.0 / 10.0;
  EXPECT_NEAR(static_cast<double>(u.size()) / o.sample_rate_hz, 3.0 * cycle_s, 0.01);
  EXPECT_DOUBLE_EQ(u.front(), 0.0);
  // The largest sample-to-sample change is a random move (at most 0.08 mm) on top of the drift
  // (2.9 um per sample) and the end ramp; no section starts with a jump.
  double max_jump = 0.0;
  for (size_t k = 1; k < u.size(); ++k) max_jump = std::max(max_jump, std::abs(u[k] - u[k - 1]));
  EXPECT_LE(max_jump, 0.08 + 0.01);
  EXPECT_GE(max_jump, 0.07);  // the random moves are there
  // The drift carries the program across the travel (80 mm) and back to the start.
  const auto [lo, hi] = std::minmax_element(u.begin(), u.end());
  EXPECT_GE(*hi - *lo, 80.0);
  EXPECT_NEAR(u.back(), 0.0, 0.1);
  // The sweep section of the first cycle (6-12 s) holds high-frequency motion: its samples change
  // sign of velocity at about twice the sweep's mean frequency.
  int reversals = 0;
  for (size_t k = 6002; k < 12000; ++k)
    if ((u[k] - u[k - 1]) * (u[k - 1] - u[k - 2]) < 0.0) ++reversals;
  EXPECT_GT(reversals, 2 * 6 * 30);  // mean frequency of a 5 -> 200 Hz exponential sweep: ~53 Hz
}

// drift_passes = 4 crosses the travel there and back four times under the same sections (12.5
// mm/s instead of 2.9, above a bearing's Stribeck speed: docs/ident.md, "Faster than the
// Stribeck speed"); the programs differ by the drifts alone.
TEST(CalibrationProgram, FourDriftPassesCrossTheTravelFourTimes) {
  CalibrationProgramOptions one;
  CalibrationProgramOptions four;
  four.drift_passes = 4;
  const std::vector<double> u1 = calibration_program(one), u4 = calibration_program(four);
  ASSERT_EQ(u1.size(), u4.size());
  const size_t n = u1.size();
  // At an eighth of the program the four-pass drift is at the travel's end (80 mm), the single
  // one at a quarter of its way out (20 mm); at a quarter, back at 0 against 40 mm.
  EXPECT_NEAR(u4[n / 8] - u1[n / 8], 80.0 - 20.0, 0.05);
  EXPECT_NEAR(u4[n / 4] - u1[n / 4], 0.0 - 40.0, 0.05);
  EXPECT_NEAR(u4[3 * n / 8] - u1[3 * n / 8], 80.0 - 60.0, 0.05);
  double max_step = 0.0;
  for (size_t k = 1; k < n; ++k)
    max_step = std::max(max_step, std::abs((u4[k] - u1[k]) - (u4[k - 1] - u1[k - 1])));
  // 4 x 160 mm over the program against 160 mm, in opposite directions on the way back.
  EXPECT_NEAR(max_step, (4.0 + 1.0) * 2.0 * 80.0 / static_cast<double>(n), 1e-6);
}

// drift_through_all = false: the drift moves through the random moves and the sweep only; the
// reversals and the runs go at their own speeds both ways.
TEST(CalibrationProgram, ADriftThatStandsStillThroughTheRunsLeavesTheirSpeeds) {
  CalibrationProgramOptions o;
  o.drift_through_all = false;
  const std::vector<double> u = calibration_program(o);
  ASSERT_EQ(u.size(), calibration_program(CalibrationProgramOptions{}).size());
  // The first cycle's 20 mm run at 10 mm/s starts after 6 s random, 6 s sweep and 3.13 s of
  // reversals (15.13 s) and turns at 17.13 s: 10 um per sample exactly, in both directions.
  for (size_t k = 15200; k < 19000; ++k) {
    if (k >= 17120 && k <= 17150) continue;  // the turn
    ASSERT_NEAR(std::abs(u[k] - u[k - 1]), 0.010, 1e-9) << "sample " << k;
  }
  // The drift still carries the program across the travel and back.
  const auto [lo, hi] = std::minmax_element(u.begin(), u.end());
  EXPECT_GE(*hi - *lo, 80.0);
  EXPECT_NEAR(u.back(), 0.0, 0.1);
}

// The drift a program adds to its sections: the program less the same sections without one.
std::vector<double> drift_of(const CalibrationProgramOptions& o) {
  CalibrationProgramOptions still;
  still.travel_mm = 0.0;  // the sections alone
  const std::vector<double> u0 = calibration_program(still), u = calibration_program(o);
  EXPECT_EQ(u0.size(), u.size());
  std::vector<double> d(std::min(u.size(), u0.size()));
  for (size_t k = 0; k < d.size(); ++k) d[k] = u[k] - u0[k];
  return d;
}

// Samples [k0, k1) of the drift move by step_mm each.
void expect_drift_steps(const std::vector<double>& d, size_t k0, size_t k1, double step_mm) {
  ASSERT_LE(k1, d.size());
  for (size_t k = k0; k < k1; ++k) ASSERT_NEAR(d[k] - d[k - 1], step_mm, 1e-9) << "sample " << k;
}

// Two drift speeds: one under the random moves and the sweep, the other under the reversals and
// the runs (a program slow where periodic errors are read and above the Stribeck speed elsewhere).
TEST(CalibrationProgram, TwoDriftSpeedsMoveUnderTheirSections) {
  CalibrationProgramOptions two;
  two.drift_speed_random_mm_s = 6.0;
  two.drift_speed_others_mm_s = 12.5;
  const std::vector<double> d = drift_of(two);
  // The first cycle: 12 s of random moves and sweep at 6 mm/s (72 mm out), then the reversals
  // and the run at 12.5 mm/s: the turn at 80 mm comes at 12.64 s, the next at 0 mm at 19.04 s.
  expect_drift_steps(d, 1, 12000, 0.006);
  expect_drift_steps(d, 12700, 19000, -0.0125);
  const std::vector<double> u = calibration_program(two);
  const auto [lo, hi] = std::minmax_element(u.begin(), u.end());
  EXPECT_GE(*hi - *lo, 80.0);
}

// A third speed for the runs alone: 0 stands the drift still there, so the runs go at their own
// speed both ways (docs/ident.md, "Faster than the Stribeck speed").
TEST(CalibrationProgram, ADriftStillUnderTheRunsLeavesThemTheirSpeed) {
  CalibrationProgramOptions three;
  three.drift_speed_random_mm_s = 6.0;
  three.drift_speed_others_mm_s = 12.5;
  three.drift_speed_runs_mm_s = 0.0;
  const std::vector<double> d = drift_of(three);
  // The first cycle: random moves and sweep to 12 s at 6 mm/s, the reversals (3.13 s) at 12.5
  // mm/s back from the turn at 80 mm (12.64 s), then the run (4 s) with the drift still.
  expect_drift_steps(d, 1, 12000, 0.006);
  expect_drift_steps(d, 12700, 15100, -0.0125);
  expect_drift_steps(d, 15200, 19100, 0.0);
  // The run's speed is the program's run_speed_mm_s both ways.
  const std::vector<double> u = calibration_program(three);
  EXPECT_NEAR((u[16500] - u[16000]) / 0.5, three.run_speed_mm_s, 1e-9);
  EXPECT_NEAR((u[18500] - u[18000]) / 0.5, -three.run_speed_mm_s, 1e-9);
}

sim::GantryAxisParams y_axis_with_resonance(double freq_hz) {
  sim::GantryAxisParams p = sim::thesis_y_axis();
  p.belt_span_mm = 1e6;  // the linear model's belt everywhere (docs/simulator.md)
  p.seed = 3;
  if (freq_hz > 0.0) p.effects.extra_resonance = {true, freq_hz, 0.05, 0.15};
  return p;
}

IdentResult identify(const sim::GantryAxisParams& p, const std::vector<double>& program) {
  auto trace = sim::record_gantry_trace(p, program, 1000.0, "y");
  EXPECT_TRUE(trace.ok());
  const AxisTrace& a = trace.value().axes[0];
  auto r = identify_axis(a.name, a.cmd_mm, a.meas_mm, trace.value().period_s(), FitOptions{});
  EXPECT_TRUE(r.ok());
  return r.value();
}

// 70 Hz with 0.15 kg on the 1.07 kg Y carriage: the refitted baseline absorbs the mass, the
// held-out RMS barely moves, the FRF misses by ~20 %.
TEST(CalibrationProgram, ResonanceAboveTheBeltModeIsNamedFromTheFrf) {
  CalibrationProgramOptions o;
  o.seed = 3;
  const IdentResult r = identify(y_axis_with_resonance(70.0), calibration_program(o));
  ASSERT_EQ(r.effects.size(), 1u);
  EXPECT_EQ(r.effects[0], Effect::kExtraResonance);
  EXPECT_NEAR(r.augmented.extra_freq_hz, 70.0, 0.25 * 70.0);
}

// The first simulator's X axis with its belt anchored so that the stiffness depends on position
// and direction (Eq. 6, the carriage 80 mm off the belt's middle), and an encoder 8.31 ms late
// (calibrate seed 1's draw). On this program the delay alone passes the margin and the ratio
// follows (rounds 1 and 2); the daemon's recording of the same machine, with its fast travel
// moves, needs the look-ahead by one effect (Calibrate.TheFirstSimulatorsEncoderDelayIs...).
TEST(CalibrationProgram, ADelayBesideTheBeltsDirectionIsNamedAsAPair) {
  sim::GantryAxisParams p = sim::thesis_x_axis();
  p.seed = 3;
  p.belt_x0_mm = 80.0;
  p.effects.time_delay = {true, 8.31};
  CalibrationProgramOptions o;
  o.seed = 3;
  auto trace = sim::record_gantry_trace(p, calibration_program(o), 1000.0, "x");
  ASSERT_TRUE(trace.ok());
  const AxisTrace& a = trace.value().axes[0];
  auto res = identify_axis(a.name, a.cmd_mm, a.meas_mm, trace.value().period_s(), FitOptions{});
  ASSERT_TRUE(res.ok());
  const IdentResult& r = res.value();
  std::printf("baseline %.3f um held out -> %.3f um; delay %.3f ms, ratio %.3f\n",
              r.baseline_validation_rms_um, r.augmented_validation_rms_um, r.augmented.delay_ms,
              r.augmented.stiffness_ratio);
  for (const auto& c : r.candidates)
    std::printf("  round %d %s%s%s %.3f%s\n", c.round, effect_name(c.effect),
                c.with >= 0 ? " after " : "",
                c.with >= 0 ? effect_name(static_cast<Effect>(c.with)) : "", c.validation_rms_um,
                c.kept ? " kept" : "");
  ASSERT_EQ(r.effects.size(), 2u);
  EXPECT_TRUE(r.augmented.has(Effect::kTimeDelay));
  EXPECT_TRUE(r.augmented.has(Effect::kDirectionStiffness));
  EXPECT_NEAR(r.augmented.delay_ms, 8.31, 0.25 * 8.31);
  EXPECT_LT(r.augmented_validation_rms_um, 0.5 * r.baseline_validation_rms_um);
}

// The second simulator (plant2/, a distributed belt, LuGre friction, field lag) as
// bench_ident_draws draws it: one axis, the calibration program of the same seed (its sweep
// ending at sweep_end_hz; the program's default unless a test needs the former 150 Hz).
IdentResult identify_plant2(uint64_t seed, plant2::EffectKind kind, double* key_true,
                            const char* key = "freq_hz", const FitOptions& fo = {},
                            double sweep_end_hz = CalibrationProgramOptions{}.sweep_f_end_hz) {
  const plant2::Draw d = plant2::draw_axis(seed, kind);
  const char axis = d.params.carriage.mass_kg < 0.5 * (0.45 + 1.07) ? 'x' : 'y';
  if (key_true != nullptr && !d.effects.empty()) *key_true = d.effects[0].param(key);
  CalibrationProgramOptions o;
  o.seed = seed;
  o.sweep_f_end_hz = sweep_end_hz;
  auto trace =
      plant2::record_axis2_trace(d.params, calibration_program(o), 1000.0, std::string(1, axis));
  EXPECT_TRUE(trace.ok());
  const AxisTrace& a = trace.value().axes[0];
  auto r = identify_axis(a.name, a.cmd_mm, a.meas_mm, trace.value().period_s(), fo);
  EXPECT_TRUE(r.ok());
  for (const auto& c : r.value().candidates)
    std::printf("  round %d %s%s%s %.3f%s\n", c.round, c.without ? "without " : "",
                effect_name(c.effect), c.from_frf ? " (read off the FRF)" : "", c.validation_rms_um,
                c.dropped ? " kept, dropped"
                : c.kept  ? " kept"
                          : "");
  return r.value();
}

// A 138.5 Hz mode on the heavy Y axis (second simulator, seed 1020). A mode of 100-150 Hz moves
// little of the trace's energy, so the time-domain screening leaves it, and it is read off the
// training part's FRF (kept where it halves the baseline's misfit near it on the held-out FRF).
// With the sweep ending at 150 Hz its last 0.1 s fade-out (142-150 Hz) left this mode half
// excited, and it was "none"; with the sweep to 200 Hz it is named at about 148 Hz.
TEST(CalibrationProgram, SecondSimulatorsModeAboveTheSweepsEnergyIsReadOffTheFrf) {
  double f_true = 0.0;
  const IdentResult former =
      identify_plant2(1020, plant2::EffectKind::extra_resonance, &f_true, "freq_hz", {}, 150.0);
  const IdentResult r = identify_plant2(1020, plant2::EffectKind::extra_resonance, &f_true);
  std::printf("drawn %.1f Hz; sweep to 150 Hz: %zu effects; to 200 Hz: %zu effects, %.1f Hz\n",
              f_true, former.effects.size(), r.effects.size(), r.augmented.extra_freq_hz);
  EXPECT_TRUE(former.effects.empty());
  ASSERT_EQ(r.effects.size(), 1u);
  EXPECT_EQ(r.effects[0], Effect::kExtraResonance);
  EXPECT_GT(f_true, 130.0);
  EXPECT_NEAR(r.augmented.extra_freq_hz, f_true, 0.25 * f_true);
  EXPECT_TRUE(std::any_of(r.candidates.begin(), r.candidates.end(), [](const CandidateResult& c) {
    return c.kept && c.from_frf && c.effect == Effect::kExtraResonance;
  }));
}

// The model without the effects a consumer does not carry (FitOptions::not_carried; feedloop
// calibrate's feedforward has no extra mode): the same draw's 111 Hz mode is named, and the
// carried model is the baseline structure refitted without it, predicting the held-out part at
// least as well as the baseline fitted alone. With nothing left out it is the augmented model.
TEST(CalibrationProgram, TheCarriedModelIsRefittedWithoutTheEffectsLeftOut) {
  FitOptions fo;
  fo.min_slope_improvement = 1.0;  // the belt uniform: this test is about the effects left out
  fo.not_carried = {Effect::kExtraResonance, Effect::kPeriodicPosition, Effect::kScaleError};
  const IdentResult r =
      identify_plant2(1024, plant2::EffectKind::extra_resonance, nullptr, "freq_hz", fo);
  ASSERT_EQ(r.effects.size(), 1u);
  EXPECT_TRUE(r.augmented.has(Effect::kExtraResonance));
  EXPECT_FALSE(r.carried.has(Effect::kExtraResonance));
  std::printf("held out: baseline %.3f, augmented %.3f, carried %.3f um\n",
              r.baseline_validation_rms_um, r.augmented_validation_rms_um,
              r.carried_validation_rms_um);
  EXPECT_LE(r.carried_validation_rms_um, r.baseline_validation_rms_um + 1e-9);
  EXPECT_GE(r.carried_validation_rms_um, r.augmented_validation_rms_um);
  FitOptions uniform;
  uniform.min_slope_improvement = 1.0;
  const IdentResult all =
      identify_plant2(1024, plant2::EffectKind::extra_resonance, nullptr, "freq_hz", uniform);
  EXPECT_TRUE(all.carried.has(Effect::kExtraResonance));
  EXPECT_EQ(all.carried.k2_n_m, all.augmented.k2_n_m);
  EXPECT_EQ(all.carried_validation_rms_um, all.augmented_validation_rms_um);
}

// The second simulator's belt is two spans in parallel whose lengths follow the carriage (plant2/
// axis2.hpp: k^ / l1 + k^ / (l2 + l3)), so it is stiffer near the motor's pulley; the
// calibration program drifts 80 mm along it. The carried model's compliance slope is fitted
// (fit.cpp) and must have the drawn belt's sign and size at the reference. Measured on the clean
// draws 1001-1007: kept on six (2.5-4.9 /m against 2.9-3.4 drawn), not on 1001 (held out 4.00
// against the carried model's ~4.0 um).
TEST(CalibrationProgram, SecondSimulatorsBeltIsStifferNearItsMotor) {
  int kept = 0;
  for (uint64_t seed : {1001u, 1002u, 1003u, 1004u, 1005u, 1006u, 1007u}) {
    const plant2::Draw d = plant2::draw_axis(seed, plant2::EffectKind::none);
    const IdentResult r = identify_plant2(seed, plant2::EffectKind::none, nullptr);
    if (r.carried.compliance_slope_per_m == 0.0) {
      std::printf("seed %llu: uniform kept (held out %.3f um with a slope, %.3f without)\n",
                  static_cast<unsigned long long>(seed), r.slope_validation_rms_um,
                  r.carried_validation_rms_um);
      EXPECT_GT(r.slope_validation_rms_um, 0.0);  // tried
      continue;
    }
    ++kept;
    // The trace counts from the carriage's rest (start_m); the belt's x from the pulley's side.
    const double x_m = d.params.start_m + r.carried.stiffness_reference_mm * 1e-3;
    const double k = plant2::Axis2::belt_stiffness_n_m(d.params.belt, x_m);
    const double dk = plant2::Axis2::belt_stiffness_n_m(d.params.belt, x_m + 1e-3) -
                      plant2::Axis2::belt_stiffness_n_m(d.params.belt, x_m - 1e-3);
    const double s_true = -dk / 2e-3 / k;  // (1 / K)' / (1 / K), 1/m
    std::printf(
        "seed %llu: compliance slope %.2f /m fitted, %.2f /m drawn at %.1f mm; held out "
        "%.3f um with it, uniform %.3f\n",
        static_cast<unsigned long long>(seed), r.carried.compliance_slope_per_m, s_true, x_m * 1e3,
        r.carried_validation_rms_um, r.baseline_validation_rms_um);
    EXPECT_GT(s_true, 1.0);
    EXPECT_NEAR(r.carried.compliance_slope_per_m, s_true, 0.6 * s_true) << "seed " << seed;
    EXPECT_LT(r.carried_validation_rms_um, r.baseline_validation_rms_um) << "seed " << seed;
  }
  EXPECT_GE(kept, 5);
}

// The clean draw whose baseline misses its FRF most near a candidate mode of the 50 clean draws
// (seed 1007, X: 0.43 within +-25 % of 76 Hz, below the 0.5 a mode must first show).
TEST(CalibrationProgram, SecondSimulatorsCleanAxisNamesNoModeFromTheFrf) {
  const IdentResult r = identify_plant2(1007, plant2::EffectKind::none, nullptr);
  EXPECT_TRUE(r.effects.empty());
}

// A heavy Y carriage with no effect drawn (second simulator, seed 5001, outside the bench's
// seeds): its own mode, about 37 Hz in the baseline, is not the two-mass model's peak (a belt of
// spans, LuGre bristles), and a third mass at 42 Hz lowered the held-out RMS by a fifth, fitted at
// a damping ratio of 0.19, the fit's bound. A mode pinned there wants more damping than a mode has
// and is refused (four such "modes" named on seeds 5000-5049, all at 39-43 Hz on the bound).
TEST(CalibrationProgram, SecondSimulatorsHeavyCarriageNamesNoModePinnedOnTheDampingBound) {
  const IdentResult r = identify_plant2(5001, plant2::EffectKind::none, nullptr);
  EXPECT_TRUE(r.effects.empty());
}

// A Y axis with no effect drawn (second simulator, seed 5031): a scale of 1.00004 was named on it,
// 40 ppm, 3 um over the program's travel, taken for what the baseline misses. A scale error is
// named from 100 ppm (FitOptions::min_scale_error; the drawn ones are 0.2-1 %).
TEST(CalibrationProgram, SecondSimulatorsCleanAxisNamesNoScaleOfAFewPpm) {
  const IdentResult r = identify_plant2(5031, plant2::EffectKind::none, nullptr);
  EXPECT_TRUE(r.effects.empty());
  EXPECT_FALSE(r.augmented.has(Effect::kScaleError));  // nor carried unnamed
}

// A belt 1.43 times stiffer pulling + than pulling - on the light X axis (second simulator, seed
// 1041): the ratio, fitted at 1.42, lowered the held-out RMS by 14 %, under the 15 % a finding
// needs, and nothing was named. A ratio that large is named at 8 %
// (FitOptions::min_improvement_direction); the clean draws fit 0.85-1.20, under the 1.22 it takes.
TEST(CalibrationProgram, SecondSimulatorsLightAxisNamesItsDirectionRatio) {
  double ratio_true = 0.0;
  const IdentResult r = identify_plant2(1041, plant2::EffectKind::direction_dependent_stiffness,
                                        &ratio_true, "ratio");
  std::printf("drawn %.3f; found %.3f; held out %.2f -> %.2f um\n", ratio_true,
              r.augmented.stiffness_ratio, r.baseline_validation_rms_um,
              r.augmented_validation_rms_um);
  ASSERT_EQ(r.effects.size(), 1u);
  EXPECT_EQ(r.effects[0], Effect::kDirectionStiffness);
  EXPECT_NEAR(r.augmented.stiffness_ratio, ratio_true, 0.25 * ratio_true);
}

// A clean X axis (second simulator, seed 1033) whose fit gives the uniform baseline a ratio of
// 0.92 for 9 % on the held-out part: under the ratio a finding takes, so not named at the
// direction's lower margin.
TEST(CalibrationProgram, SecondSimulatorsCleanAxisNamesNoSmallDirectionRatio) {
  const IdentResult r = identify_plant2(1033, plant2::EffectKind::none, nullptr);
  EXPECT_TRUE(r.effects.empty());
  EXPECT_FALSE(r.augmented.has(Effect::kDirectionStiffness));
}

// A 3.2 N friction on the light X axis (second simulator, seed 1008). The baseline fitted without
// it bends around it (k2 561 kN/m, c1 12 kN s/m; the clean draw of the seed: 65 kN/m, 8 N s/m),
// and the friction screened from there stayed in that valley: 13.1 N, read through a k2 of
// 270 kN/m. Screened from the preset's baseline too, the start that predicts the held-out part
// better is kept: about 2.9 N.
TEST(CalibrationProgram, SecondSimulatorsFrictionIsNotReadThroughABentBaseline) {
  double force_true = 0.0;
  const IdentResult r =
      identify_plant2(1008, plant2::EffectKind::coulomb_friction, &force_true, "force_n");
  std::printf("drawn %.3f N; found %.3f N, k2 %.4g N/m\n", force_true, r.augmented.friction_force_n,
              r.augmented.k2_n_m);
  ASSERT_EQ(r.effects.size(), 1u);
  EXPECT_EQ(r.effects[0], Effect::kCoulombFriction);
  EXPECT_NEAR(r.augmented.friction_force_n, force_true, 0.25 * force_true);
}

// A microstep error of 5.5 um once per full step (0.17 mm) on the heavy Y axis of second-simulator
// seed 1002, whose carriage also drags (every draw has 0.05-0.25 N of LuGre friction). Neither
// passes the margin alone (held-out 9.4 um: the error 8.0, a friction 6.9); together they take it
// to 3.8. The drag is below what coulomb_friction names (0.5 N), so the pair was refused and
// nothing was named; now the drag is carried unnamed and the error is named.
TEST(CalibrationProgram, SecondSimulatorsMicrostepErrorIsNamedBesideTheCarriagesDrag) {
  double amplitude_true = 0.0;
  const IdentResult r =
      identify_plant2(1002, plant2::EffectKind::periodic_position, &amplitude_true, "amplitude_um");
  std::printf("drawn %.3f um; found %.3f um at %.4f mm; drag %s %.3f N; held out %.2f -> %.2f um\n",
              amplitude_true, r.augmented.periodic_amplitude_um(), r.augmented.period_mm,
              r.drag_in_baseline ? "carried" : "not carried", r.augmented.friction_force_n,
              r.baseline_validation_rms_um, r.augmented_validation_rms_um);
  ASSERT_EQ(r.effects.size(), 1u);
  EXPECT_EQ(r.effects[0], Effect::kPeriodicPosition);
  EXPECT_NEAR(r.augmented.periodic_amplitude_um(), amplitude_true, 0.25 * amplitude_true);
  EXPECT_TRUE(r.drag_in_baseline);
  EXPECT_TRUE(r.augmented.has(Effect::kCoulombFriction));
  EXPECT_LT(r.augmented.friction_force_n, FitOptions{}.min_friction_n);
  EXPECT_LT(r.augmented_validation_rms_um, 0.6 * r.baseline_validation_rms_um);
  // The report names one effect and says what else the model carries.
  const std::string md = report_markdown(r, "seed1002.csv", ReportExtras{});
  EXPECT_NE(md.find("carries the carriage's own drag"), std::string::npos);
  EXPECT_NE(md.find("carried, unnamed"), std::string::npos);
  EXPECT_NE(report_json(r).find("the carriage's drag"), std::string::npos);
}

// A LuGre friction of 1.7 N (F_s 2.0 N) on the light X axis of second-simulator seed 1012, recorded
// with the former 5-150 Hz sweep. Its lost motion on reversal screens as a backlash first (held
// out 19.3 um: backlash 5.8, friction 7.6), and the friction then passes beside the backlash. The
// backward check refits each without the other. Until the model's belt was simulated in the
// regime each substep begins in (ident/axis_model.cpp), the friction alone (5.0 um) predicted the
// held-out part within the margin of the pair and the backlash was dropped; simulated exactly, a
// dead band beside the friction predicts it better (4.29 um; 5.29 without the band, 6.35
// without the friction), so both stay named: the band takes up part of the LuGre breakaway that
// the Dahl friction lacks. (Of 100 draws of bench_ident_draws, friction and backlash, none has
// the check drop an effect now; docs/ident.md, "The belt's regimes".)
TEST(CalibrationProgram, SecondSimulatorsFrictionIsFoundWhereABacklashScreensFirst) {
  double force_true = 0.0;
  const IdentResult r = identify_plant2(1012, plant2::EffectKind::coulomb_friction, &force_true,
                                        "force_n", {}, 150.0);
  std::printf("drawn %.3f N; found %.3f N; held out %.2f -> %.2f um\n", force_true,
              r.augmented.friction_force_n, r.baseline_validation_rms_um,
              r.augmented_validation_rms_um);
  ASSERT_TRUE(r.augmented.has(Effect::kCoulombFriction));
  EXPECT_NE(std::find(r.effects.begin(), r.effects.end(), Effect::kCoulombFriction),
            r.effects.end());
  EXPECT_NEAR(r.augmented.friction_force_n, force_true, 0.25 * force_true);
  EXPECT_LT(r.augmented_validation_rms_um, 0.3 * r.baseline_validation_rms_um);
  // The backward check refitted the pair each without the other, and each absence cost more than
  // the margin.
  int without = 0;
  for (const CandidateResult& c : r.candidates) {
    without += c.without ? 1 : 0;
    if (c.without) {
      EXPECT_GT(c.validation_rms_um, 1.15 * r.augmented_validation_rms_um);
    }
  }
  EXPECT_EQ(without, static_cast<int>(r.effects.size()));
}

// The same draw with its carriage weighed (FitOptions::carriage_mass_kg, here 0.9 kg for the
// preset's 0.45): the fit's models are scaled to that mass as a whole, so the positions, the fit
// and the names are the preset's and the force comes out in the weighed carriage's newtons. (With
// the start scaled instead, 2 % more mass moved this friction by 6 %: the fit is local.)
TEST(CalibrationProgram, AWeighedCarriageScalesTheForceAndChangesNothingElse) {
  const double mass_kg = 0.9;
  double force_true = 0.0;
  const IdentResult preset =
      identify_plant2(1008, plant2::EffectKind::coulomb_friction, &force_true, "force_n");
  FitOptions fo;
  fo.carriage_mass_kg = mass_kg;
  const IdentResult weighed =
      identify_plant2(1008, plant2::EffectKind::coulomb_friction, nullptr, "force_n", fo);
  const double r = mass_kg / preset.augmented.m2_kg;
  std::printf("mass %.3f kg (x%.3f): %.3f N -> %.3f N (drawn %.3f); held out %.3f -> %.3f um\n",
              mass_kg, r, preset.augmented.friction_force_n, weighed.augmented.friction_force_n,
              force_true, preset.augmented_validation_rms_um, weighed.augmented_validation_rms_um);
  EXPECT_NEAR(r, 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(weighed.augmented.m2_kg, mass_kg);
  ASSERT_EQ(weighed.effects, preset.effects);
  EXPECT_DOUBLE_EQ(weighed.augmented_validation_rms_um, preset.augmented_validation_rms_um);
  EXPECT_NEAR(weighed.augmented.friction_force_n, r * preset.augmented.friction_force_n,
              1e-9 * preset.augmented.friction_force_n);
  EXPECT_NEAR(weighed.augmented.k2_n_m, r * preset.augmented.k2_n_m,
              1e-9 * preset.augmented.k2_n_m);
}

TEST(CalibrationProgram, CleanAxisNamesNothing) {
  CalibrationProgramOptions o;
  o.seed = 3;
  const IdentResult r = identify(y_axis_with_resonance(0.0), calibration_program(o));
  EXPECT_TRUE(r.effects.empty());
}

// The first simulator's motor is Eq. 13's exactly (sim/gantry_axis.hpp: its field lags by c1 /
// k1): the field lag is tried and Eq. 13's motor kept.
TEST(CalibrationProgram, FirstSimulatorsMotorKeepsEq13) {
  CalibrationProgramOptions o;
  o.seed = 3;
  const IdentResult r = identify(y_axis_with_resonance(0.0), calibration_program(o));
  EXPECT_GT(r.field_lag_validation_rms_um, 0.0);
  EXPECT_EQ(r.carried.field_lag_ms, 0.0);
}

// The drive's own periodic error: a microstep table's error once per full step (0.1697 mm), on
// the second simulator's seed 1035 (5.3 um at the carriage, quasi-static, on a 1.08 kg carriage).
// With the program's drift held still the trace has the constant-speed runs at 10 mm/s, where it
// is a 59 Hz ripple above the carriage's belt mode (as in feedloop calibrate's program), and the
// ramps into them. The whole held-out part does not name it; tested on the held-out samples where
// it shows whole (FitOptions::full_step_mm) it is named, at the full step, with its size. The
// same machine without it names nothing there.
TEST(CalibrationProgram, TheDrivesMicrostepErrorIsNamedWhereItShows) {
  constexpr uint64_t kSeed = 1035;
  const double full_step_mm = 2.0 * std::numbers::pi * 5.40 / 200.0;
  auto identify = [&](plant2::EffectKind kind, double full_step) {
    const plant2::Draw d = plant2::draw_axis(kSeed, kind);
    CalibrationProgramOptions o;
    o.seed = kSeed;
    o.travel_mm = 0.0;
    auto trace = plant2::record_axis2_trace(d.params, calibration_program(o), 1000.0, "y");
    EXPECT_TRUE(trace.ok());
    const AxisTrace& a = trace.value().axes[0];
    FitOptions fo;
    fo.full_step_mm = full_step;
    auto r = identify_axis(a.name, a.cmd_mm, a.meas_mm, trace.value().period_s(), fo);
    EXPECT_TRUE(r.ok());
    return r.value();
  };
  const plant2::Draw drawn = plant2::draw_axis(kSeed, plant2::EffectKind::periodic_position);
  ASSERT_NE(drawn.effects[0].source.find("once per full step"), std::string::npos);
  const double amplitude_um = drawn.effects[0].param("amplitude_um");
  const IdentResult without = identify(plant2::EffectKind::periodic_position, 0.0);
  EXPECT_FALSE(without.augmented.has(Effect::kPeriodicPosition));
  const IdentResult with = identify(plant2::EffectKind::periodic_position, full_step_mm);
  ASSERT_EQ(with.effects.size(), 1u);
  EXPECT_EQ(with.effects[0], Effect::kPeriodicPosition);
  EXPECT_NEAR(with.augmented.period_mm, full_step_mm, 0.01 * full_step_mm);
  EXPECT_NEAR(with.augmented.periodic_amplitude_um(), amplitude_um, 0.25 * amplitude_um);
  auto band_kept = [](const IdentResult& r) {
    return std::count_if(r.candidates.begin(), r.candidates.end(),
                         [](const CandidateResult& c) { return c.from_band && c.kept; });
  };
  EXPECT_EQ(band_kept(with), 1);  // named by the test where it shows, and only that candidate
  EXPECT_EQ(band_kept(without), 0);
  EXPECT_TRUE(identify(plant2::EffectKind::none, full_step_mm).effects.empty());
}

}  // namespace
}  // namespace feedloop::ident
