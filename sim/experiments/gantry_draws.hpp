// Random machines for judging identification (issue 15): a thesis axis (X or Y) with its own
// parameters drawn around the thesis's and at most one undeclared effect of a given kind with a
// drawn size, plus the ground truth the identification should report.
//
// Ranges (each uniform; docs/ident.md "Judged on random draws"):
//   machine: k1, k2, c1, c2 x 0.8 .. 1.25; m1, m2 x 0.9 .. 1.1 (the identification fixes the
//            thesis's masses: a weighing error)
//   periodic_position  period 20 .. 40 mm, amplitude 8 .. 30 um
//   coulomb_friction   0.8 .. 4 N
//   backlash           15 .. 60 um
//   direction_dependent_stiffness  ratio 1.4 .. 2.2 (from the belt's anchor, span 350 mm)
//   extra_resonance    25 .. 80 Hz, damping 0.03 .. 0.1, mass 0.1 .. 0.25 kg
//   time_delay         2 .. 10 ms
//   scale_error        |scale - 1| 0.002 .. 0.01, either sign
// Owner: the caller. Pure function of (seed, kind).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "ident/axis_model.hpp"
#include "sim/gantry_params.hpp"

namespace feedloop::sim {

struct DrawnGantryAxis {
  GantryAxisParams params;
  char axis = 'x';                      // the thesis preset it was drawn around ('x' or 'y')
  std::optional<ident::Effect> effect;  // the one undeclared effect; nothing on a clean draw
  std::string key_param;                // the parameter judged, as ident names it ("" when clean)
  double key_value = 0.0;               // its true value
  bool needs_fixed_position = false;    // the effect depends on position (direction stiffness)
};

// `kind` empty: a clean draw.
DrawnGantryAxis draw_gantry_axis(uint64_t seed, std::optional<ident::Effect> kind);

}  // namespace feedloop::sim
