// Random machines of the second simulator: the axis's own parameters drawn around the thesis's
// (Tables 2-4) within stated plausible ranges, plus exactly one effect of a chosen kind with a
// drawn size, and the ground truth in the identification's vocabulary (DESIGN.md,
// "Identification report"). Reproducible from the seed on every standard library (core/rng.hpp).
// The same seed gives the same baseline machine whatever the kind (two streams).
//
// Ranges (docs/plant2.md has the reasons):
//   periodic_position  runout: period 2 pi r = 33.93 mm, amplitude 10-40 um;
//                      microstep error once per full step (0.1696 mm) or once per electrical cycle
//                      (0.6786 mm), amplitude 4-12 um (quasi-static carriage amplitude)
//   coulomb_friction   force_n 1.5-5 N (the LuGre model's F_c; F_s = 1.1-1.4 F_c)
//   backlash           width_um 20-120 um (total dead band at the pulley's teeth)
//   direction_dependent_stiffness  ratio K(pulling +) / K(pulling -) 1.3-2.0 or its reciprocal
//   extra_resonance    freq_hz 40-150 Hz (damping 0.02-0.08, mass 15-35 % of the carriage's)
//   time_delay         delay_ms 0.3-2.0 ms
//   scale_error        scale 1 +- (0.002-0.008) (measured travel / commanded travel)
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "plant2/params.hpp"

namespace feedloop::plant2 {

enum class EffectKind {
  none,
  periodic_position,
  coulomb_friction,
  backlash,
  direction_dependent_stiffness,
  extra_resonance,
  time_delay,
  scale_error,
};

inline constexpr std::array<EffectKind, 8> kAllEffectKinds = {
    EffectKind::none,
    EffectKind::periodic_position,
    EffectKind::coulomb_friction,
    EffectKind::backlash,
    EffectKind::direction_dependent_stiffness,
    EffectKind::extra_resonance,
    EffectKind::time_delay,
    EffectKind::scale_error,
};

// The vocabulary's name ("none" for none) and back.
const char* effect_name(EffectKind kind);
std::optional<EffectKind> effect_kind_from_name(std::string_view name);

// One effect's ground truth: its name, its parameters (the key parameter first) in the
// vocabulary's units, and where in the machine it comes from (e.g. "pulley runout").
struct TrueEffect {
  std::string name;
  std::vector<std::pair<std::string, double>> params;
  std::string source;

  const std::string& key_name() const { return params.front().first; }
  double key_value() const { return params.front().second; }
  // The parameter's value, or NaN when absent.
  double param(std::string_view name) const;
};

struct Draw {
  uint64_t seed = 0;
  EffectKind kind = EffectKind::none;
  Axis2Params params;
  std::vector<TrueEffect> effects;  // empty for EffectKind::none, else exactly one
};

// The machine for `seed` with one effect of `kind` (none: the baseline only).
Draw draw_axis(uint64_t seed, EffectKind kind);

// Whether a drawn effect's parameters lie in the ranges stated above.
bool in_stated_range(const TrueEffect& e);

// One line per line of the ground truth: "name key=value ... (source)" or "none".
std::string describe(const Draw& d);

}  // namespace feedloop::plant2
