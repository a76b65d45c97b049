// Random machines of the second simulator (plant2/draw.hpp): reproducible from the seed, every
// kind's size in its stated range, the baseline the same for every kind, and every draw a machine
// that runs (tracks a move, stays finite) and records a trace whose cmd and meas agree.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "plant2/axis2.hpp"
#include "plant2/draw.hpp"
#include "plant2/recording.hpp"

namespace feedloop::plant2 {
namespace {

TEST(Draw, NamesRoundTrip) {
  for (EffectKind k : kAllEffectKinds) {
    auto back = effect_kind_from_name(effect_name(k));
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(*back, k);
  }
  EXPECT_FALSE(effect_kind_from_name("wobble").has_value());
}

TEST(Draw, ReproducibleFromTheSeed) {
  for (EffectKind k : kAllEffectKinds) {
    const Draw a = draw_axis(42, k);
    const Draw b = draw_axis(42, k);
    EXPECT_EQ(describe(a), describe(b));
    EXPECT_EQ(a.params.carriage.mass_kg, b.params.carriage.mass_kg);
    EXPECT_EQ(a.params.belt.specific_stiffness_n, b.params.belt.specific_stiffness_n);
    EXPECT_EQ(a.params.stepper.holding_torque_nm, b.params.stepper.holding_torque_nm);
    EXPECT_EQ(a.params.encoder.delay_s, b.params.encoder.delay_s);
    // The baseline does not depend on the kind.
    const Draw none = draw_axis(42, EffectKind::none);
    EXPECT_EQ(a.params.carriage.mass_kg, none.params.carriage.mass_kg);
    EXPECT_EQ(a.params.belt.specific_stiffness_n, none.params.belt.specific_stiffness_n);
  }
  EXPECT_NE(draw_axis(1, EffectKind::none).params.carriage.mass_kg,
            draw_axis(2, EffectKind::none).params.carriage.mass_kg);
  // A known value pins the generator (SplitMix64, core/rng.hpp) across standard libraries.
  const Draw d = draw_axis(7, EffectKind::backlash);
  ASSERT_EQ(d.effects.size(), 1u);
  EXPECT_EQ(d.effects[0].name, "backlash");
}

TEST(Draw, EveryKindsSizeLiesInItsStatedRange) {
  for (EffectKind k : kAllEffectKinds) {
    std::set<std::string> sources;
    double lo = 1e300, hi = -1e300;
    for (uint64_t seed = 1; seed <= 300; ++seed) {
      const Draw d = draw_axis(seed, k);
      ASSERT_TRUE(validate(d.params).ok()) << describe(d);
      if (k == EffectKind::none) {
        EXPECT_TRUE(d.effects.empty());
        EXPECT_EQ(d.params.encoder.scale, 1.0);
        EXPECT_EQ(d.params.encoder.delay_s, 0.0);
        EXPECT_EQ(d.params.belt.backlash_m, 0.0);
        EXPECT_EQ(d.params.carriage.extra_mass_kg, 0.0);
        EXPECT_LE(d.params.carriage.coulomb_n, 0.25);
        continue;
      }
      ASSERT_EQ(d.effects.size(), 1u);
      const TrueEffect& e = d.effects[0];
      EXPECT_EQ(e.name, effect_name(k));
      EXPECT_TRUE(in_stated_range(e)) << describe(d);
      sources.insert(e.source);
      lo = std::min(lo, e.key_value());
      hi = std::max(hi, e.key_value());
    }
    if (k == EffectKind::periodic_position) {
      EXPECT_EQ(sources.size(), 3u);  // every source drawn
    }
    if (k != EffectKind::none) {
      std::printf("%-30s %s in [%.4g, %.4g]\n", effect_name(k),
                  draw_axis(1, k).effects[0].key_name().c_str(), lo, hi);
    }
  }
}

TEST(Draw, EveryKindRunsAndRecords) {
  // A 20 mm move out and back at 40 mm/s, recorded at 1 kHz: cmd is the microstep staircase,
  // meas follows it within what the axis's dynamics and effects allow, nothing blows up.
  std::vector<double> prog;
  for (int i = 0; i <= 1200; ++i) {
    const double t = i * 1e-3;
    prog.push_back(t < 0.5 ? 40.0 * t : (t < 0.6 ? 20.0 : std::max(0.0, 20.0 - 40.0 * (t - 0.6))));
  }
  for (EffectKind k : kAllEffectKinds) {
    for (uint64_t seed : {3u, 11u}) {
      const Draw d = draw_axis(seed, k);
      auto tr = record_axis2_trace(d.params, prog, 1000.0, "x");
      ASSERT_TRUE(tr.ok()) << tr.error().message;
      const ident::AxisTrace& a = tr->axes[0];
      ASSERT_EQ(a.cmd_mm.size(), prog.size());
      const double step = mm_per_microstep(d.params.stepper);
      double worst = 0.0;
      for (size_t i = 0; i < prog.size(); ++i) {
        ASSERT_TRUE(std::isfinite(a.meas_mm[i]));
        EXPECT_NEAR(a.cmd_mm[i] / step, std::round(a.cmd_mm[i] / step), 1e-6);
        worst = std::max(worst, std::fabs(a.meas_mm[i] - a.cmd_mm[i]));
      }
      EXPECT_LT(worst, 0.5) << describe(d);
      // At rest at the end, back home: within the effects' static sizes (backlash, friction).
      EXPECT_NEAR(a.meas_mm.back(), 0.0, 0.12) << describe(d);
      if (k == EffectKind::scale_error) {
        // Held at 20 mm: meas / cmd is the drawn scale.
        const size_t held = 590;
        EXPECT_NEAR(a.meas_mm[held] / a.cmd_mm[held], d.params.encoder.scale, 8e-4) << describe(d);
      }
    }
  }
}

}  // namespace
}  // namespace feedloop::plant2
