// The identification report: DIR/report.json exactly per the DESIGN.md contract
//   {"axis": "x", "baseline": {"model": "...", "rms_um": 12.3},
//    "effects": [{"name": "periodic_position", "params": {"period_mm": 33.9, "amplitude_um": 25.0}}],
//    "augmented": {"model": "...", "rms_um": 3.1}}
// and a human-readable DIR/report.md (fitted parameters, Eq. 17 coefficients, the candidates
// tried each round with their held-out RMS, before/after), plus DIR/residual.csv (time, residual
// before and after, for plotting).
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"
#include "ident/fit.hpp"

namespace feedloop::ident {

// (name, value) pairs of an effect's parameters in the vocabulary's units.
std::vector<std::pair<std::string, double>> effect_params_report(const AxisModel& m, Effect e);

// One-line model descriptions for report.json.
std::string baseline_description(const AxisModel& m);
std::string augmented_description(const IdentResult& r);

std::string report_json(const IdentResult& r);
std::string report_markdown(const IdentResult& r, const std::string& trace_name);

// Writes report.json, report.md and residual.csv into dir (created if missing).
Status write_report(const std::string& dir, const IdentResult& r, const std::vector<double>& time_s,
                    const std::string& trace_name);

}  // namespace feedloop::ident
